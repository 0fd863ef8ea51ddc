"""The closed-loop experiment of docs/experiments.md: realism, controllability and safety of each method
on held-out synthesized windows and on real scenes, one table per dataset.

    python -m langtraj.sim.experiments --checkpoint CKPT --data NAME=LABELS_DIR[:SPLIT] [...] \
        [--windows N] [--rollouts R] [--candidates M] [--json OUT]

Each window gets one ground-truth prompt from its InterDrive labels: an interaction prompt whose agents
the model drives, else a single-agent one (windows with neither are skipped). Methods: constant velocity,
log replay, LangTraj without text, with the prompt, with the CTG++-style guidance baseline (the prompt's
labels as guidance costs, no text), and with collision guidance (the prompt's other agent drives into its
target agent) without and with the prompt. Figures: the WOSAC 2025 meta-metric and buckets, the prompted
agents' minADE, the collision rate of all sim agents, the vehicles' offroad rate (none without road
edges) and, for collision guidance, the adversary-target collision rate.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from langtraj.errors import InputError
from langtraj.fileio import atomic_path
from langtraj.guidance import CollisionCost, GuidanceTerm
from langtraj.interdrive.dataset import PromptEntry, WindowRecord
from langtraj.metrics.controllability import collision_rate, min_ade, offroad_rate, pair_collision_rate
from langtraj.metrics.features import SceneMap
from langtraj.metrics.wosac import evaluate_scenario
from langtraj.scenario.model import Scenario
from langtraj.scenario.selection import prioritized_agents
from langtraj.sim.engine import SimConfig, simulate
from langtraj.sim.policies import (
    ConstantVelocityPolicy,
    GuidanceBaselinePolicy,
    LangTrajPolicy,
    LogReplayPolicy,
    Policy,
)
from langtraj.training.data import SceneDataset

METHODS = (
    "constant velocity",
    "log replay",
    "LangTraj, no text",
    "LangTraj, text",
    "LangTraj, guidance baseline (CTG++ style)",
    "LangTraj, collision guidance",
    "LangTraj, collision guidance + text",
)
COLUMNS = ("meta", "kinematic", "interactive", "map", "minade", "collision", "offroad", "pair_collision")


@dataclass(frozen=True)
class Case:
    """One window to simulate and the prompt it is conditioned on (interaction prompts: target, other)."""

    scenario: Scenario
    prompt: PromptEntry


def choose_prompt(record: WindowRecord, driven_ids: set[int]) -> PromptEntry | None:
    """The window's first interaction prompt whose agents are all driven, else its first such single-agent
    prompt (None when no prompt fits)."""
    fits = [p for p in record.prompts if p.mentions and set(p.mentions) <= driven_ids]
    interaction = [p for p in fits if p.subtype is not None and len(p.mentions) >= 2]
    return (interaction or fits or [None])[0]


def cases(labels_dir: str, split: str, max_windows: int | None, max_agents: int) -> tuple[list[Case], int]:
    """Windows of `split` with a usable prompt (at most `max_windows`) and how many were skipped."""
    dataset = SceneDataset(labels_dir, split=split, augment=False)
    found, skipped = [], 0
    for index, record in enumerate(dataset.records):
        if max_windows is not None and len(found) >= max_windows:
            break
        scenario = dataset.window(index)
        driven = prioritized_agents(scenario, max_agents)
        ids = {int(i) for i in scenario.agents.ids[driven]}
        future_ok = scenario.num_steps - scenario.current_index - 1 >= 80
        prompt = choose_prompt(record, ids) if future_ok else None
        if prompt is None:
            skipped += 1
            continue
        found.append(Case(scenario, prompt))
    return found, skipped


def _policies(module, case: Case, candidates: int, steps: int) -> dict[str, Callable[[], Policy]]:
    model, data = module.model, module.train_config.data
    prompt = case.prompt
    common = {"candidates": candidates, "steps": steps}
    makers: dict[str, Callable[[], Policy]] = {
        "constant velocity": ConstantVelocityPolicy,
        "log replay": LogReplayPolicy,
        "LangTraj, no text": lambda: LangTrajPolicy(model, data, **common),
        "LangTraj, text": lambda: LangTrajPolicy(model, data, prompt=prompt, **common),
        "LangTraj, guidance baseline (CTG++ style)": lambda: GuidanceBaselinePolicy(
            model, data, prompt=prompt, **common
        ),
    }
    if len(prompt.mentions) >= 2:
        slots = LangTrajPolicy.slots(case.scenario, prioritized_agents(case.scenario, data.max_agents))
        target, adversary = slots[prompt.mentions[0]], slots[prompt.mentions[1]]
        collide = [GuidanceTerm(CollisionCost(adversary, target), 1.0)]
        makers["LangTraj, collision guidance"] = lambda: LangTrajPolicy(model, data, terms=collide, **common)
        makers["LangTraj, collision guidance + text"] = lambda: LangTrajPolicy(
            model, data, prompt=prompt, terms=collide, **common
        )
    return makers


def score(case: Case, rollouts, scene_map: SceneMap, pair: bool) -> dict[str, float]:
    """The table's figures for one method on one window."""
    wosac = evaluate_scenario(case.scenario, rollouts, "2025", scene_map=scene_map)
    prompted = list(case.prompt.mentions)
    out = {
        "meta": wosac.metametric,
        "kinematic": wosac.kinematic_metrics,
        "interactive": wosac.interactive_metrics,
        "map": wosac.map_based_metrics,
        "minade": min_ade(case.scenario, rollouts, prompted).mean,
        "collision": collision_rate(case.scenario, rollouts),
        "offroad": math.nan,
        "pair_collision": math.nan,
    }
    if scene_map.road_edges is not None:
        with contextlib.suppress(InputError):  # raised when no sim agent is a vehicle
            out["offroad"] = offroad_rate(case.scenario, rollouts, scene_map=scene_map)
    if pair:
        target, adversary = case.prompt.mentions[:2]
        out["pair_collision"] = pair_collision_rate(case.scenario, rollouts, adversary, target)
    return out


def run_experiment(module, all_cases: list[Case], config: SimConfig, candidates: int, steps: int) -> dict:
    """Mean figures per method over the cases (NaN-aware), with per-window figures and timings."""
    rows: dict[str, list[dict[str, float]]] = {m: [] for m in METHODS}
    seconds: dict[str, float] = dict.fromkeys(METHODS, 0.0)
    for case in all_cases:
        scene_map = SceneMap.from_scenario(case.scenario)
        for name, make in _policies(module, case, candidates, steps).items():
            start = time.perf_counter()
            result = simulate(case.scenario, make(), config)
            seconds[name] += time.perf_counter() - start
            pair = len(case.prompt.mentions) >= 2  # every method: the unguided rate is the reference
            rows[name].append(
                score(case, result.rollouts, scene_map, pair) | {"scenario_id": case.scenario.scenario_id}
            )
    table = {}
    for name, values in rows.items():
        if not values:
            continue
        table[name] = {c: _nanmean([v[c] for v in values]) for c in COLUMNS} | {
            "windows": len(values),
            "seconds": seconds[name],
        }
    return {"table": table, "per_window": rows}


def _nanmean(values: list[float]) -> float:
    finite = [v for v in values if not math.isnan(v)]
    return float(np.mean(finite)) if finite else math.nan


def markdown(table: dict[str, dict[str, float]]) -> str:
    """The table as Markdown (NaN shown as a dash)."""

    def cell(v: float) -> str:
        return "–" if math.isnan(v) else f"{v:.3f}"

    head = (
        "| method | meta | kinematic | interactive | map | minADE (m) | collision | offroad | adv.–target collision |"
    )
    lines = [head, "|" + " --- |" * 9]
    for name, r in table.items():
        lines.append(f"| {name} | " + " | ".join(cell(r[c]) for c in COLUMNS) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    from langtraj.training.run import module_from_checkpoint

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--checkpoint", required=True)
    parser.add_argument("--data", action="append", required=True, help="NAME=LABELS_DIR[:SPLIT] (default split val)")
    parser.add_argument("--windows", type=int, default=None, help="at most this many windows per dataset")
    parser.add_argument("--rollouts", type=int, default=8)
    parser.add_argument("--candidates", type=int, default=4)
    parser.add_argument("--steps", type=int, default=5, help="DDIM steps")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", help="also write every figure here")
    args = parser.parse_args(argv)
    module = module_from_checkpoint(args.checkpoint)
    config = SimConfig(rollouts=args.rollouts, seed=args.seed)
    results = {}
    for item in args.data:
        name, _, rest = item.partition("=")
        folder, _, split = rest.partition(":")
        found, skipped = cases(folder, split or "val", args.windows, module.train_config.data.max_agents)
        result = run_experiment(module, found, config, args.candidates, args.steps)
        result["skipped_windows"] = skipped
        results[name] = result
        print(
            f"\n{name}: {len(found)} windows ({skipped} skipped: no prompt whose agents the model drives), "
            f"{args.rollouts} rollouts, {args.candidates} candidates per replan, K = {args.steps}"
        )
        print(markdown(result["table"]))
    if args.json:
        with atomic_path(args.json) as tmp:
            tmp.write_text(json.dumps(results, indent=1, default=float))


if __name__ == "__main__":
    main()
