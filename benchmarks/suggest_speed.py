"""Seconds `langtraj suggest` takes to search one scene (the map indexed, then every pair behaviour asked of every
vehicle and cyclist in reach of the ego: `interdrive.suggest.suggest_stagings`), on the largest real scene in
../shared/data/real (the most agents valid at the current step), on every other real scene, and on a synthesized
200-agent scene built here: six eastbound lanes of a 1-km road, each listing its neighbours, with 180 vehicles 13 m
apart (8-16 m/s), crossed at x = 9 by a two-way road with 20 more (its lanes junction lanes), the ego in a middle lane
near the crossing, so that about half the agents are in reach. Reading the file is timed apart. Medians over
--repeats runs, one process.

    python benchmarks/suggest_speed.py [--repeats 5] [--data DIR] [--seed 0]
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time
from pathlib import Path

import numpy as np

from langtraj.interdrive.suggest import DEFAULT_RADIUS_M, count_by_behaviour, suggest_stagings
from langtraj.roads import MapIndex
from langtraj.scenario import Agents, AgentType, LaneNeighbor, MapFeature, MapFeatureType, RoadMap, Scenario
from langtraj.scenario.io import expand_scenario_paths, read_scenario

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data" / "real"
STEPS = 91


def synthesized_scene(num_agents: int = 200, seed: int = 0) -> Scenario:
    """The 200-agent scene of the module docstring (track ids 1..N, the first the self-driving car)."""
    rng = np.random.default_rng(seed)
    xs = np.linspace(-500.0, 500.0, 201)
    features, lanes = [], 6
    for k in range(lanes):
        pts = np.stack([xs, np.full_like(xs, 3.5 * k), np.zeros_like(xs)], axis=1)
        nb = {
            side: (LaneNeighbor(10 + k + step, 0, len(xs) - 1, 0, len(xs) - 1),) if 0 <= k + step < lanes else ()
            for side, step in (("left", 1), ("right", -1))
        }
        features.append(
            MapFeature(
                10 + k, MapFeatureType.LANE_SURFACE_STREET, pts, left_neighbors=nb["left"], right_neighbors=nb["right"]
            )
        )
    ys = np.linspace(-300.0, 300.0, 121)
    for k, (x, direction) in enumerate(((8.75 - 1.75, 1.0), (8.75 + 1.75, -1.0))):
        pts = np.stack([np.full_like(ys, x), ys[::-1] if direction < 0 else ys, np.zeros_like(ys)], axis=1)
        features.append(MapFeature(30 + k, MapFeatureType.LANE_SURFACE_STREET, pts, interpolating=True))
    starts = []  # (x, y, heading, speed)
    highway = num_agents - 20
    for i in range(highway):
        lane, slot = i % lanes, i // lanes
        starts.append((-200.0 + 13.0 * slot + rng.uniform(-2, 2), 3.5 * lane, 0.0, rng.uniform(8.0, 16.0)))
    for i in range(num_agents - highway):
        north = i % 2 == 0
        y = -60.0 + 15.0 * (i // 2) + rng.uniform(-2, 2)
        starts.append((7.0 if north else 10.5, y if north else -y, np.pi / 2 if north else -np.pi / 2, 9.0))
    ego = min(range(highway), key=lambda i: abs(starts[i][0] + 20.0) + abs(starts[i][1] - 7.0))
    starts.insert(0, starts.pop(ego))
    t = (np.arange(STEPS) - 10) * 0.1
    states = np.zeros((len(starts), STEPS, 9), np.float32)
    for a, (x, y, heading, speed) in enumerate(starts):
        states[a, :, 0] = x + np.cos(heading) * speed * t
        states[a, :, 1] = y + np.sin(heading) * speed * t
        states[a, :, 3] = heading
        states[a, :, 4] = np.cos(heading) * speed
        states[a, :, 5] = np.sin(heading) * speed
        states[a, :, 6:9] = (4.5, 2.0, 1.6)
    return Scenario(
        scenario_id=f"synth-{num_agents}",
        timestamps=np.arange(STEPS) * 0.1,
        current_index=10,
        sdc_index=0,
        agents=Agents(
            ids=np.arange(1, len(starts) + 1),
            types=np.full(len(starts), int(AgentType.VEHICLE), np.int8),
            states=states,
            valid=np.ones((len(starts), STEPS), bool),
        ),
        road_map=RoadMap(tuple(features)),
        metadata={"origin": "benchmarks/suggest_speed.py"},
    )


def _search(scenario: Scenario) -> tuple[float, int, dict[str, int]]:
    """Seconds to index the map and search the scene, and what was found."""
    start = time.perf_counter()
    stagings = suggest_stagings(scenario, map_index=MapIndex.build(scenario.road_map))
    return time.perf_counter() - start, len(stagings), count_by_behaviour(stagings)


def _report(name: str, scenario: Scenario, repeats: int, read_s: float | None = None) -> float:
    seconds, found, counts = zip(*(_search(scenario) for _ in range(repeats)), strict=True)
    c = scenario.current_index
    ego = scenario.agents.states[scenario.sdc_index, c, :2]
    valid = scenario.agents.valid[:, c]
    near = valid & (np.linalg.norm(scenario.agents.states[:, c, :2] - ego, axis=1) <= DEFAULT_RADIUS_M)
    median = statistics.median(seconds)
    read = "" if read_s is None else f", read {read_s:.2f} s"
    kinds = ", ".join(f"{k} {v}" for k, v in counts[0].items() if v) or "none"
    print(
        f"{name}: {scenario.num_agents} agents ({int(valid.sum())} valid now, {int(near.sum()) - 1} within 80 m of "
        f"the ego): search median {median:.2f} s (min {min(seconds):.2f}, max {max(seconds):.2f}){read}; "
        f"{found[0]} stagings ({kinds})",
        flush=True,
    )
    return median


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--data", type=Path, default=DATA, help="folder of real scenes")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, Python "
          f"{platform.python_version()}; medians of {args.repeats}")  # fmt: skip
    _report("synthesized", synthesized_scene(seed=args.seed), args.repeats)
    if not args.data.is_dir():
        print(f"no real scenes in {args.data}")
        return
    scenes = []
    for path in expand_scenario_paths([args.data]):
        start = time.perf_counter()
        scenario = read_scenario(path)
        scenes.append((time.perf_counter() - start, path, scenario))
    scenes.sort(key=lambda x: -int(x[2].agents.valid[:, x[2].current_index].sum()))
    for i, (read_s, path, scenario) in enumerate(scenes):
        _report(("largest real " if i == 0 else "") + path.name, scenario, args.repeats, read_s)


if __name__ == "__main__":
    main()
