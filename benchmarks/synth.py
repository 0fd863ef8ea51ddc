"""Scenario factory throughput (windows per core-minute, per kind) and a realism table per kind.

Runs shards one after another in this process (one core; netconvert's time is included), then reads
the written windows back and measures, over every valid step of every agent, what WOSAC would see:
p99 |acceleration| and p99 |yaw rate| of vehicles from positions and headings, p99 pedestrian
speed from positions (jumps of the pedestrian model would show here), the fraction of
vehicle/cyclist pairs whose boxes overlap at some step, and the event counts. The real WOMD scene in
../shared (when present) is measured the same way for comparison.

    python benchmarks/synth.py [--kinds all] [--shards 2] [--windows-per-shard 40] [--duration SECONDS]
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

from langtraj.angles import wrap_angle
from langtraj.scenario.io import read_scenarios
from langtraj.scenario.model import STEP_SECONDS, Scenario
from langtraj.scenario.types import AgentType, StateField
from langtraj.synth.network import parse_kinds
from langtraj.synth.shard import ShardConfig, ShardTask, run_shard, shard_seed
from langtraj.synth.windows import boxes_overlap

REAL = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "real" / "motion_data_one_scenario.tfrecord"


def kinematics(scenarios: list[Scenario]) -> tuple[np.ndarray, np.ndarray]:
    """|acceleration| and |yaw rate| of vehicles at steps where three consecutive states are valid."""
    accels, yaws = [], []
    for s in scenarios:
        vehicles = s.agents.types == AgentType.VEHICLE
        st, valid = s.agents.states[vehicles].astype(np.float64), s.agents.valid[vehicles]
        xy = st[..., [StateField.X, StateField.Y]]
        speed = np.linalg.norm(np.diff(xy, axis=1), axis=-1) / STEP_SECONDS
        ok2 = valid[:, 1:] & valid[:, :-1]
        accel = np.diff(speed, axis=1) / STEP_SECONDS
        ok3 = ok2[:, 1:] & ok2[:, :-1]
        accels.append(np.abs(accel[ok3]))
        yaw = wrap_angle(np.diff(st[..., StateField.HEADING], axis=1)) / STEP_SECONDS
        yaws.append(np.abs(yaw[ok2]))
    return np.concatenate(accels or [np.zeros(0)]), np.concatenate(yaws or [np.zeros(0)])


def pedestrian_speeds(scenarios: list[Scenario]) -> np.ndarray:
    """Pedestrian speeds from positions at steps where two consecutive states are valid."""
    speeds = []
    for s in scenarios:
        peds = s.agents.types == AgentType.PEDESTRIAN
        xy = s.agents.states[peds][..., [StateField.X, StateField.Y]].astype(np.float64)
        valid = s.agents.valid[peds]
        speed = np.linalg.norm(np.diff(xy, axis=1), axis=-1) / STEP_SECONDS
        speeds.append(speed[valid[:, 1:] & valid[:, :-1]])
    return np.concatenate(speeds or [np.zeros(0)])


def overlap_fraction(scenarios: list[Scenario]) -> float:
    """Fraction of vehicle/cyclist pairs (per window) whose boxes overlap at some step (no shrinking)."""
    pairs = overlapping = 0
    for s in scenarios:
        idx = np.flatnonzero(s.agents.types != AgentType.PEDESTRIAN)
        for a in range(len(idx)):
            for b in range(a + 1, len(idx)):
                pair = idx[[a, b]]
                pairs += 1
                overlapping += boxes_overlap(s.agents.states[pair], s.agents.valid[pair], s.agents.types[pair], 0.0)
    return overlapping / max(pairs, 1)


def realism_row(name: str, scenarios: list[Scenario]) -> str:
    accel, yaw = kinematics(scenarios)
    ped = pedestrian_speeds(scenarios)
    events = Counter(e.kind for s in scenarios for e in s.events)
    p99 = lambda v: float(np.percentile(v, 99)) if v.size else float("nan")  # noqa: E731
    return (
        f"| {name} | {len(scenarios)} | {p99(accel):.2f} | {p99(yaw):.3f} | {p99(ped):.2f} "
        f"| {overlap_fraction(scenarios):.4f} "
        f"| {events['lane_change']} | {events['yield']} | {events['yield_to_pedestrian']} | {events['ped_crossing']} |"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kinds", default="all")
    parser.add_argument("--shards", type=int, default=2, help="shards (seeds) per kind")
    parser.add_argument("--windows-per-shard", type=int, default=40)
    parser.add_argument("--duration", type=float, help="simulated seconds per shard (default: automatic)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    config = ShardConfig(duration_s=args.duration)
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, python {platform.python_version()}, no GPU used")
    length = "automatic length" if args.duration is None else f"{args.duration:.0f} s"
    print(f"shards per kind {args.shards}, {args.windows_per_shard} windows per shard, {length}\n")
    throughput, realism, all_rates = [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        for kind in parse_kinds(args.kinds):
            rates, windows, scenarios = [], 0, []
            for index in range(args.shards):
                path = Path(tmp) / f"{kind}-{index}.tfrecord"
                task = ShardTask(kind, index, shard_seed(args.seed, kind, index), args.windows_per_shard, path)
                began = time.perf_counter()
                outcome = run_shard(task, config)
                seconds = time.perf_counter() - began
                rates.append(outcome.windows / seconds * 60.0)
                windows += outcome.windows
                scenarios.extend(read_scenarios(path) if outcome.windows else [])
            all_rates.extend(rates)
            agents = [s.num_agents for s in scenarios]
            throughput.append(
                f"| {kind} | {windows} | {statistics.median(rates):.0f} | {min(rates):.0f}-{max(rates):.0f} "
                f"| {statistics.median(agents) if agents else 0:.0f} |"
            )
            realism.append(realism_row(kind, scenarios))
            print(throughput[-1], flush=True)
    print("\n| kind | windows | windows/core-min (median) | range | agents/window (median) |")
    print("| --- | --- | --- | --- | --- |")
    print("\n".join(throughput))
    print(f"\noverall median {statistics.median(all_rates):.0f} windows per core-minute over {len(all_rates)} shards\n")
    print("| kind | windows | p99 abs accel (m/s^2) | p99 abs yaw rate (rad/s) | p99 pedestrian speed (m/s) "
          "| overlapping pairs | lane changes | yields | yields to pedestrians | pedestrian crossings |")  # fmt: skip
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    print("\n".join(realism))
    if REAL.is_file():
        print(realism_row("real WOMD scene (reference)", list(read_scenarios(REAL))))


if __name__ == "__main__":
    main()
