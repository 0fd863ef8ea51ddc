"""Seconds for the map costs' nearest-segment search (`langtraj.guidance.geometry.nearest_segment`, a
k-d tree over segment pieces) against comparing every point with every segment, on random segments
and points the size of a guided simulation's query (4 candidates x 8 rollouts x 20 agents x 80 steps).

    python benchmarks/nearest_segment.py [--segments 2900] [--points 51200] [--repeats 3]
"""

from __future__ import annotations

import argparse
import statistics
import time

import torch


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--segments", type=int, default=2900)
    parser.add_argument("--points", type=int, default=51200)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()

    from langtraj.guidance import geometry

    generator = torch.Generator().manual_seed(0)
    start = torch.rand(args.segments, 2, generator=generator) * 300.0
    end = start + torch.randn(args.segments, 2, generator=generator) * 2.0
    points = torch.rand(args.points, 2, generator=generator) * 250.0 + 25.0
    timings = {"tree": [], "every pair": []}
    for _ in range(args.repeats):
        for name, search in (("tree", geometry.nearest_segment), ("every pair", geometry._brute_force)):
            begin = time.perf_counter()
            search(points, start, end)
            timings[name].append(time.perf_counter() - begin)
    tree, brute = (statistics.median(timings[k]) for k in ("tree", "every pair"))
    print(f"{args.points} points, {args.segments} segments, torch threads {torch.get_num_threads()}")
    print(f"tree: median {tree:.3f} s; every pair: median {brute:.3f} s; ratio {brute / tree:.1f}x")


if __name__ == "__main__":
    main()
