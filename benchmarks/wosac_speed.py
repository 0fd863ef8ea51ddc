"""Seconds to score one scenario with 32 rollouts under the WOSAC 2025 metrics, for 50 and 128 sim agents.

Scenes: the shared Waymo scenario (50 sim agents) and the same scene grown to 128 sim agents by adding
copies of its tracks, shifted along the road map by a few metres (so the map, the signals and the
evaluation set, the SDC plus 4 tracks to predict, stay real). A `--evaluated N` option raises the
evaluation set to the challenge maximum (SDC + 8). Rollouts: log replay with 0.05 m noise, 32
rollouts. Each figure is the median of `--repeats` runs of `evaluate_scenario`, map indexing included.

    python benchmarks/wosac_speed.py [--scenario FILE] [--repeats 5] [--evaluated 9]
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from langtraj.metrics.wosac import evaluate_scenario
from langtraj.rollouts import sim_agent_indices
from langtraj.rollouts.baselines import generate_baseline
from langtraj.scenario.io import read_scenario
from langtraj.scenario.model import Agents, Scenario
from langtraj.scenario.types import StateField

DEFAULT_SCENARIO = (
    Path(__file__).resolve().parents[2] / "shared" / "data" / "real" / "motion_data_one_scenario.tfrecord"
)


def grow(scenario: Scenario, num_sim: int, seed: int = 0) -> Scenario:
    """The scene with shifted copies of its sim agents added until it has `num_sim` sim agents."""
    rng = np.random.default_rng(seed)
    agents = scenario.agents
    sim = sim_agent_indices(scenario)
    extra = num_sim - len(sim)
    if extra <= 0:
        return scenario
    source = rng.choice(sim, size=extra)
    states = agents.states[source].copy()
    shift = rng.uniform(-6.0, 6.0, size=(extra, 1, 2)).astype(np.float32)
    states[..., [StateField.X, StateField.Y]] += shift
    ids = agents.ids.max() + 1 + np.arange(extra)
    grown = Agents(
        ids=np.concatenate([agents.ids, ids]),
        types=np.concatenate([agents.types, agents.types[source]]),
        states=np.concatenate([agents.states, states]),
        valid=np.concatenate([agents.valid, agents.valid[source]]),
        tracks_to_predict=agents.tracks_to_predict,
        prediction_difficulty=agents.prediction_difficulty,
        objects_of_interest=agents.objects_of_interest,
    )
    return replace(scenario, agents=grown)


def with_evaluated(scenario: Scenario, count: int) -> Scenario:
    """Tracks to predict extended (with sim agents, in order) so SDC + tracks number `count`."""
    sim = [int(i) for i in sim_agent_indices(scenario) if i != scenario.sdc_index]
    chosen = list(scenario.agents.tracks_to_predict)
    for index in sim:
        if len(chosen) + 1 >= count:
            break
        if index not in chosen:
            chosen.append(index)
    agents = replace(
        scenario.agents, tracks_to_predict=np.array(chosen, np.int64), prediction_difficulty=np.zeros(len(chosen))
    )
    return replace(scenario, agents=agents)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenario", type=Path, default=DEFAULT_SCENARIO)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--evaluated", type=int, default=0, help="evaluated agents (0: the scene's own)")
    parser.add_argument("--agents", type=int, nargs="+", default=[50, 128])
    args = parser.parse_args()
    base = read_scenario(args.scenario)
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, numpy {np.__version__}")
    for num in args.agents:
        scene = grow(base, num)
        if args.evaluated:
            scene = with_evaluated(scene, args.evaluated)
        rollouts = generate_baseline("log_replay", scene, 32, seed=0, noise_std=0.05)
        times = []
        for _ in range(args.repeats):
            start = time.perf_counter()
            metrics = evaluate_scenario(scene, rollouts, "2025")
            times.append(time.perf_counter() - start)
        evaluated = 1 + len(scene.agents.tracks_to_predict)
        print(
            f"{rollouts.num_agents:4d} sim agents, {evaluated} evaluated, 32 rollouts: "
            f"median {statistics.median(times):.3f} s (min {min(times):.3f}, max {max(times):.3f}, "
            f"{args.repeats} runs); metametric {metrics.metametric:.4f}"
        )


if __name__ == "__main__":
    main()
