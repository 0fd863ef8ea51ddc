"""The on-road cost's road field against the exact nearest-segment search it replaces in simulations, on
the real WOMD maps in ../shared/data/real: seconds to build the field, seconds per lookup of the
signed road-edge distance (field and exact search), and how far the field's values and gradients are
from the exact ones.

Points are spread around each scene's sim agents (their current positions plus noise growing to 15 m,
as far as a simulation's candidates wander), `--points` per scene. Errors are split by the exact
signed distance: within 1 m of an edge (where the on-road cost's margin puts its weight), 1 to 4 m off
the road, and farther (only off-road points pay there). Medians over --repeats runs for the times.

    python benchmarks/road_field.py [--points 200000] [--repeats 3] [--threads 1]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import torch

REAL = Path(__file__).resolve().parents[2] / "shared" / "data" / "real"
SCENES = (
    "motion_data_one_scenario.tfrecord",
    "sd_training.tfrecord-00000-of-01000_2a1e44d405a6833f.pkl",
    "sd_training.tfrecord-00000-of-01000_8a346109094cd5aa.pkl",
)
BANDS = ((-1.0, 1.0, "within 1 m of an edge"), (1.0, 4.0, "1-4 m off the road"), (4.0, 1e9, "farther off"))


def timed(function, repeats: int):
    """(median seconds, last result) of `repeats` calls."""
    times, result = [], None
    for _ in range(repeats):
        begin = time.perf_counter()
        result = function()
        times.append(time.perf_counter() - begin)
    return statistics.median(times), result


def with_gradient(function, points: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """function(points) [P] and its gradient [P, 2]."""
    x = points.clone().requires_grad_(True)
    value = function(x)
    (grad,) = torch.autograd.grad(value.sum(), x)
    return value.detach(), grad


def measure(path: Path, points_wanted: int, repeats: int) -> list[str]:
    """The table rows of one scene."""
    from langtraj.frames import points_to_frame
    from langtraj.guidance import GuidanceScene
    from langtraj.guidance.costs import signed_edge_distance
    from langtraj.model.features import scene_frame
    from langtraj.scenario.io import read_scenario
    from langtraj.sim.policies import model_agents

    scenario = read_scenario(path)
    agents = model_agents(scenario)
    origin = scene_frame(scenario)
    scene = GuidanceScene.from_scenario(scenario, origin, agents)
    here = points_to_frame(scenario.agents.states[agents, scenario.current_index, :2].astype(np.float64), origin)
    centre = torch.as_tensor(here, dtype=torch.float32)
    per_agent = points_wanted // len(agents)
    spread = torch.linspace(0.0, 15.0, per_agent)[None, :, None]
    noise = torch.randn(len(agents), per_agent, 2, generator=torch.Generator().manual_seed(0))
    points = (centre[:, None] + noise * spread).reshape(-1, 2)

    build, field_scene = timed(lambda: scene.with_road_field(cover=centre), repeats)
    field = field_scene.road_field
    lookup, (value, grad) = timed(lambda: with_gradient(lambda x: field.sample(x)[0], points), repeats)
    edges = scene.road_edges
    search, (exact, exact_grad) = timed(lambda: with_gradient(lambda x: signed_edge_distance(x, edges), points), 1)
    inside = field.sample(points)[1]
    cosine = (grad * exact_grad).sum(-1) / (grad.norm(dim=-1) * exact_grad.norm(dim=-1)).clamp(min=1e-9)
    error = (value - exact).abs()
    grid = f"{field.shape[1]} x {field.shape[0]} at {field.resolution:.2f} m"
    head = f"| {scenario.scenario_id} | {len(edges)} | {grid} | {build:.2f} s | {lookup:.3f} s | {search:.2f} s"
    rows = []
    for low, high, band in BANDS:
        chosen = inside & (exact >= low) & (exact < high)
        e = error[chosen]
        rows.append(
            f"{head} | {band} | {int(chosen.sum())} | {e.median():.4f} m | {e.quantile(0.99):.3f} m "
            f"| {(e > 0.05).float().mean():.1%} | {(cosine[chosen] < 0.99).float().mean():.1%} |"
        )
        head = "| | | | | |"
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--points", type=int, default=200_000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    print(f"{args.points} points per scene, {args.threads} torch thread(s), medians of {args.repeats}\n")
    print(
        "| scene | edge segments | grid | build | lookup: field | lookup: exact | band | points | |error| median "
        "| 99th pct | share > 5 cm | gradient cosine < 0.99 |"
    )
    print("|" + " --- |" * 12)
    for name in SCENES:
        path = REAL / name
        if not path.is_file():
            sys.exit(f"benchmark scene not found: {path}")
        print("\n".join(measure(path, args.points, args.repeats)))


if __name__ == "__main__":
    main()
