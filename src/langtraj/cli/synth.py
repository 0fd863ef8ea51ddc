"""`langtraj synth`: synthesize interactive scenario windows with SUMO into TFRecord shards. See README.md."""

from __future__ import annotations

import argparse
from pathlib import Path

from langtraj.errors import InputError


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "synth",
        help="synthesize interactive 9.1 s scenario windows with SUMO (WOMD TFRecord shards)",
        description="Simulate randomized road networks and traffic with SUMO and write 91-step windows "
        "with ground-truth behaviour events as WOMD-compatible TFRecord shards plus manifest.json. "
        "Shards are zstd-compressed (KIND-NNNN.tfrecord.zst, about 10x smaller; every LangTraj reader opens "
        "them, `zstd -d` gives a plain TFRecord). "
        "Rerunning with the same arguments resumes: finished shards are skipped.",
    )
    p.add_argument("--kinds", default="all", help="comma-separated kinds, or 'all' (see --list-kinds)")
    p.add_argument("--windows", type=int, default=200, help="windows in all, split evenly over the kinds")
    p.add_argument("--seed", type=int, default=0, help="run seed; same seed, byte-identical shards")
    p.add_argument("--workers", type=int, default=1, help="shards at once (one simulation per process)")
    p.add_argument(
        "--executor",
        default="process",
        choices=("process", "ray"),
        help="where shards run: local processes, or a Ray cluster (RAY_ADDRESS, else a local one)",
    )
    p.add_argument("--out", help="output folder (shards/, manifest.json)")
    p.add_argument("--windows-per-shard", type=int, default=40, help="most windows one simulation writes")
    p.add_argument(
        "--duration", type=float, help="simulated seconds per shard (default: enough for --windows-per-shard)"
    )
    p.add_argument(
        "--no-compress",
        action="store_true",
        help="write plain .tfrecord shards instead of zstd-compressed .tfrecord.zst (for TensorFlow readers)",
    )
    p.add_argument("--list-kinds", action="store_true", help="print the kinds and exit")
    p.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from langtraj.synth.factory import FactoryConfig, run_factory
    from langtraj.synth.network import get_kind, kind_names, parse_kinds
    from langtraj.synth.shard import ShardConfig

    if args.list_kinds:
        for name in kind_names():
            print(f"{name:12s} {get_kind(name).description}")
        return 0
    if not args.out:
        raise InputError("--out is required", where="langtraj synth")
    for name, value, low in (("--windows", args.windows, 1), ("--workers", args.workers, 1)):
        if value < low:
            raise InputError(f"must be at least {low}, got {value}", where=name)
    if args.windows_per_shard < 1:
        raise InputError(f"must be at least 1, got {args.windows_per_shard}", where="--windows-per-shard")
    if args.duration is not None and not 30.0 <= args.duration <= 3600.0:
        raise InputError(f"must be within [30, 3600] seconds, got {args.duration}", where="--duration")
    config = FactoryConfig(
        kinds=parse_kinds(args.kinds),
        windows=args.windows,
        seed=args.seed,
        out=Path(args.out),
        workers=args.workers,
        executor=args.executor,
        windows_per_shard=args.windows_per_shard,
        shard=ShardConfig(duration_s=args.duration),
        compress=not args.no_compress,
    )
    manifest = run_factory(config, progress=not args.no_progress)
    for kind, stats in manifest["per_kind"].items():
        agents = stats["agents_per_window"]
        print(
            f"{kind:12s} {stats['windows']:5d} windows  agents/window median {agents.get('median', 0):.0f}  "
            f"events {sum(stats['events'].values())}"
        )
    print(f"{manifest['windows']} windows -> {Path(args.out) / 'manifest.json'}")
    return 0
