"""`langtraj features`: build and describe feature stores, the precomputed training samples that let the
input pipeline keep up with training (docs/model.md, 'The feature store').

    langtraj features build --config CONFIG --labels LABELS_DIR [--out STORE] [--workers N]
    langtraj features build --config CONFIG SCENARIOS... --out STORE [--workers N]   # stage 1, no labels
    langtraj features info STORE
"""

from __future__ import annotations

import argparse
from pathlib import Path

from langtraj.errors import InputError


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "features",
        help="precompute training samples into a feature store (build, info)",
        description="Compute every window's scene sample once for a training preset's sample settings, so "
        "training reads arrays instead of decoding windows.",
    )
    sub = p.add_subparsers(dest="action", required=True, metavar="ACTION")
    build = sub.add_parser("build", help="build a store from a labels folder or from scenario files")
    build.add_argument("scenarios", nargs="*", metavar="SCENARIOS", help="scenario files or folders (no labels)")
    build.add_argument("--config", required=True, type=Path, help="training preset whose `data` settings to use")
    build.add_argument("--labels", type=Path, help="InterDrive labels folder (instead of SCENARIOS)")
    build.add_argument("--out", type=Path, help="store folder (default with --labels: LABELS/features/<digest>)")
    build.add_argument("--workers", type=int, default=1, help="chunks built at once")
    build.add_argument("--executor", default="process", choices=("process", "ray"), help="where chunks run")
    build.set_defaults(func=run_build)
    info = sub.add_parser("info", help="print a store's windows, settings and size")
    info.add_argument("store", type=Path, help="store folder")
    info.set_defaults(func=run_info)


def run_build(args: argparse.Namespace) -> int:
    from langtraj.scenario.io import expand_scenario_paths
    from langtraj.training.config import load_config
    from langtraj.training.store import build_store, default_store_path, labelled_jobs, scenario_jobs

    if args.workers < 1:
        raise InputError(f"must be >= 1, got {args.workers}", where="--workers")
    if bool(args.labels) == bool(args.scenarios):
        raise InputError("give either --labels LABELS_DIR or scenario files", where="langtraj features build")
    config = load_config(args.config).data
    if args.labels:
        out = args.out or default_store_path(args.labels, config)
        jobs = labelled_jobs(args.labels, config)
    else:
        if args.out is None:
            raise InputError("required with scenario files", where="--out")
        out = args.out
        jobs = scenario_jobs(expand_scenario_paths(args.scenarios), config)
    store = build_store(jobs, out, workers=args.workers, executor=args.executor)
    print(f"feature store {out}: {len(store)} windows")
    return 0


def run_info(args: argparse.Namespace) -> int:
    from langtraj.training.store import FeatureStore

    store = FeatureStore(args.store)
    size = sum(f.stat().st_size for f in args.store.rglob("*") if f.is_file())
    key = ", ".join(f"{k} {v}" for k, v in store.meta["key"].items())
    print(f"{args.store}: {len(store)} windows in {len(store.chunks)} chunks, {size / 2**20:.1f} MiB")
    print(f"sample settings: {key}")
    return 0
