"""Seconds for the map costs' nearest-segment search (`langtraj.guidance.geometry.nearest_segment`, an
STR-tree over the segments) against comparing every point with every segment.

Two workloads, medians over --repeats runs:
- `womd`: the road edges of the real WOMD scene 2a1e44d405a6833f (../shared/data/real; 6,044 segments,
  most of them 0.5 m long) and points where its 66 sim agents could be over 8 s (their current
  positions plus spreading noise), as many as a guided simulation queries per denoising step
  (4 candidates x 4 rollouts x 66 agents x 80 steps);
- `random`: random 2-m segments and uniform points (what the first benchmark used).

    python benchmarks/nearest_segment.py [--workload womd|random] [--points N] [--repeats 3]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import torch

SCENE = Path(__file__).resolve().parents[2] / "shared" / "data" / "real"
SCENE = SCENE / "sd_training.tfrecord-00000-of-01000_2a1e44d405a6833f.pkl"


def womd(points: int, generator: torch.Generator) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Road-edge segments of the real scene and `points` points around its sim agents, in its scene frame."""
    from langtraj.frames import points_to_frame
    from langtraj.guidance import GuidanceScene
    from langtraj.model.features import scene_frame
    from langtraj.scenario.io import read_scenario
    from langtraj.sim.policies import model_agents

    if not SCENE.is_file():
        sys.exit(f"benchmark scene not found: {SCENE}")
    scenario = read_scenario(SCENE)
    agents = model_agents(scenario)
    origin = scene_frame(scenario)
    edges = GuidanceScene.from_scenario(scenario, origin, agents).road_edges
    now = scenario.agents.states[agents, scenario.current_index, :2].astype(np.float64)
    centre = torch.as_tensor(points_to_frame(now, origin), dtype=torch.float32)  # [A, 2]
    steps = max(1, points // len(agents))
    spread = torch.linspace(0.0, 15.0, steps)[None, :, None]  # metres of uncertainty growing over 8 s
    noise = torch.randn(len(agents), steps, 2, generator=generator) * spread
    return edges[:, 0], edges[:, 1], (centre[:, None] + noise).reshape(-1, 2)[:points]


def random_segments(segments: int, points: int, generator: torch.Generator):
    start = torch.rand(segments, 2, generator=generator) * 300.0
    end = start + torch.randn(segments, 2, generator=generator) * 2.0
    return start, end, torch.rand(points, 2, generator=generator) * 250.0 + 25.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--workload", choices=("womd", "random"), default="womd")
    parser.add_argument("--points", type=int, default=4 * 4 * 66 * 80)
    parser.add_argument("--segments", type=int, default=2900, help="random workload only")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()

    from langtraj.guidance import geometry

    generator = torch.Generator().manual_seed(0)
    if args.workload == "womd":
        start, end, points = womd(args.points, generator)
    else:
        start, end, points = random_segments(args.segments, args.points, generator)
    timings = {"tree": [], "every pair": []}
    for _ in range(args.repeats):
        for name, search in (("tree", geometry.nearest_segment), ("every pair", geometry._brute_force)):
            begin = time.perf_counter()
            search(points, start, end)
            timings[name].append(time.perf_counter() - begin)
    tree, brute = (statistics.median(timings[k]) for k in ("tree", "every pair"))
    print(f"{args.workload}: {len(points)} points, {len(start)} segments, torch threads {torch.get_num_threads()}")
    print(f"tree: median {tree:.3f} s; every pair: median {brute:.3f} s; ratio {brute / tree:.1f}x")


if __name__ == "__main__":
    main()
