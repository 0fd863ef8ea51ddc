"""How fast the training input pipeline builds samples: milliseconds per `SceneDataset` item on one CPU core, as
a DataLoader worker builds them, for a training config's sample settings on a labelled dataset.

Without a feature store, every item is built twice over the same indices: first from cold (each window read and
decoded from its shard), then again with the windows already decoded (the dataset's per-process cache, sized to
hold them all). With the labels folder's feature store for the config (`langtraj features build`), or `--data`
naming a store, the same items are built from it as training builds them. `--profile` adds a cProfile table of
the first pass (the functions with the most cumulative time), to show where a sample's time goes.

    python benchmarks/input_speed.py --config configs/tiny.yaml --data runs/tiny/labels [--samples 200]
        [--split train] [--profile]

The last line is `ms per sample: X`: the feature store's figure when there is one (what training pays with it),
else the cold pass. See docs/benchmarks.md ('Training input pipeline').
"""

from __future__ import annotations

import argparse
import cProfile
import io
import platform
import pstats
import statistics
import time

import torch


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", required=True, help="training config (YAML); its `data` section is used")
    parser.add_argument("--data", required=True, help="InterDrive labels folder (langtraj interdrive build)")
    parser.add_argument("--samples", type=int, default=200, help="items built per pass (default 200)")
    parser.add_argument("--split", default="train", choices=["train", "val", "all"])
    parser.add_argument("--profile", action="store_true", help="print where the cold pass spends its time")
    args = parser.parse_args()
    if args.samples < 1:
        parser.error("--samples must be >= 1")

    from langtraj.training.config import load_config
    from langtraj.training.data import SceneDataset
    from langtraj.training.store import is_store

    torch.set_num_threads(1)  # a DataLoader worker's share
    config = load_config(args.config)
    stored = SceneDataset(args.data, config.data, split=args.split, seed=config.seed)
    count = min(args.samples, len(stored))
    print(
        f"machine: {platform.processor() or platform.machine()}, one thread; config {args.config} "
        f"({config.data.max_agents} agents, {config.data.max_polylines} map pieces of "
        f"{config.data.points_per_polyline} points, augment {stored.augment}); {count} of {len(stored)} "
        f"{args.split} windows; feature store: {stored.store.path if stored.store else 'none'}"
    )
    profiler = cProfile.Profile() if args.profile else None
    passes: list[tuple[str, list[float]]] = []
    if not is_store(args.data):
        decoding = SceneDataset(
            args.data, config.data, split=args.split, seed=config.seed, cache_size=count, store=None
        )
        passes.append(("cold (window read and decoded)", _one_pass(decoding, count, profiler)))
        passes.append(("windows already decoded", _one_pass(decoding, count, None)))
    if stored.store is not None:
        passes.append(("feature store", _one_pass(stored, count, profiler if not passes else None)))
    for name, times in passes:
        print(
            f"{name}: mean {1e3 * statistics.fmean(times):.2f} ms, median {1e3 * statistics.median(times):.2f} ms, "
            f"max {1e3 * max(times):.2f} ms"
        )
    if profiler is not None:
        out = io.StringIO()
        pstats.Stats(profiler, stream=out).sort_stats("cumulative").print_stats(25)
        print(out.getvalue())
    print(f"ms per sample: {1e3 * statistics.fmean(passes[-1 if stored.store else 0][1]):.2f}")
    return 0


def _one_pass(dataset, count: int, profiler: cProfile.Profile | None) -> list[float]:
    """Seconds per item for items 0..count-1, profiled when a profiler is given."""
    times = []
    if profiler is not None:
        profiler.enable()
    for index in range(count):
        start = time.perf_counter()
        dataset[index]
        times.append(time.perf_counter() - start)
    if profiler is not None:
        profiler.disable()
    return times


if __name__ == "__main__":
    raise SystemExit(main())
