"""The closed-loop experiment of docs/experiments.md: realism, controllability and safety of each method
on held-out synthesized windows and on real scenes, one table per dataset.

    langtraj experiment closed-loop --checkpoint CKPT --data NAME=LABELS_DIR[:SPLIT[:ROLLOUTS]] [...] \
        [--windows N] [--rollouts R] [--candidates M] [--json OUT]
    langtraj experiment closed-loop --config configs/experiments/closed-loop.yaml   # the same as YAML

Each window gets one ground-truth prompt from its InterDrive labels: an interaction prompt whose agents
the model drives, else a single-agent one (windows with neither are skipped). Methods: constant velocity,
log replay, LangTraj without text, with the prompt, with the CTG++-style guidance baseline (the prompt's
labels as guidance costs, no text), and with collision guidance (the prompt's other agent drives into its
target agent) without and with the prompt. Figures: the WOSAC 2025 meta-metric and buckets, the prompted
agents' minADE, the collision rate of all sim agents, the vehicles' offroad rate (none without road
edges) and, for collision guidance, the adversary-target collision rate.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from langtraj.experiments.base import EXPERIMENTS, Experiment
from langtraj.experiments.common import (
    DatasetSpec,
    SimulationSettings,
    cell,
    held_out_windows,
    markdown_table,
    nanmean,
    safety_figures,
    wosac_figures,
)
from langtraj.guidance import CollisionCost, GuidanceTerm
from langtraj.interdrive.dataset import PromptEntry, WindowRecord
from langtraj.metrics.controllability import min_ade, pair_collision_rate
from langtraj.metrics.features import SceneMap
from langtraj.model.checkpoint import load_model
from langtraj.scenario.model import Scenario
from langtraj.sim.checkpoints import checkpoint_path
from langtraj.sim.config import SimConfig, SimRequest
from langtraj.sim.engine import simulate
from langtraj.sim.policies import (
    ConstantVelocityPolicy,
    GuidanceBaselinePolicy,
    LangTrajPolicy,
    LoadedModel,
    LogReplayPolicy,
    Policy,
    model_agents,
    slots_of,
)

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


def cases(spec: DatasetSpec, max_windows: int | None) -> tuple[list[Case], int]:
    """Windows of the spec's split with a usable prompt (at most `max_windows`) and how many were skipped."""
    found, skipped = [], 0
    for record, scenario in held_out_windows(spec):
        if max_windows is not None and len(found) >= max_windows:
            break
        driven = model_agents(scenario)
        ids = {int(i) for i in scenario.agents.ids[driven]}
        prompt = choose_prompt(record, ids) if scenario.logs_future() else None
        if prompt is None:
            skipped += 1
            continue
        found.append(Case(scenario, prompt))
    return found, skipped


def _policies(loaded: LoadedModel, case: Case, candidates: int, steps: int) -> dict[str, Callable[[], Policy]]:
    model, data = loaded
    prompt = case.prompt
    request = SimRequest(candidates=candidates, steps=steps)
    makers: dict[str, Callable[[], Policy]] = {
        "constant velocity": ConstantVelocityPolicy,
        "log replay": LogReplayPolicy,
        "LangTraj, no text": lambda: LangTrajPolicy(model, data, request),
        "LangTraj, text": lambda: LangTrajPolicy(model, data, request, prompt=prompt),
        "LangTraj, guidance baseline (CTG++ style)": lambda: GuidanceBaselinePolicy(
            model, data, request, prompt=prompt
        ),
    }
    if len(prompt.mentions) >= 2:
        slots = slots_of(case.scenario, model_agents(case.scenario))
        target, adversary = slots[prompt.mentions[0]], slots[prompt.mentions[1]]
        collide = [GuidanceTerm(CollisionCost(adversary, target), 1.0)]
        makers["LangTraj, collision guidance"] = lambda: LangTrajPolicy(model, data, request, terms=collide)
        makers["LangTraj, collision guidance + text"] = lambda: LangTrajPolicy(
            model, data, request, prompt=prompt, terms=collide
        )
    return makers


def score(case: Case, rollouts, scene_map: SceneMap, pair: bool) -> dict[str, float]:
    """The table's figures for one method on one window."""
    out = wosac_figures(case.scenario, rollouts, scene_map) | safety_figures(case.scenario, rollouts, scene_map)
    out |= {"minade": min_ade(case.scenario, rollouts, list(case.prompt.mentions)).mean, "pair_collision": math.nan}
    if pair:
        target, adversary = case.prompt.mentions[:2]
        out["pair_collision"] = pair_collision_rate(case.scenario, rollouts, adversary, target)
    return out


def run_experiment(loaded: LoadedModel, all_cases: list[Case], config: SimConfig, candidates: int, steps: int) -> dict:
    """Mean figures per method over the cases (NaN-aware), with per-window figures and timings."""
    rows: dict[str, list[dict[str, float]]] = {m: [] for m in METHODS}
    seconds: dict[str, float] = dict.fromkeys(METHODS, 0.0)
    for case in all_cases:
        scene_map = SceneMap.from_scenario(case.scenario)
        for name, make in _policies(loaded, case, candidates, steps).items():
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
        table[name] = {c: nanmean([v[c] for v in values]) for c in COLUMNS} | {
            "windows": len(values),
            "seconds": seconds[name],
        }
    return {"table": table, "per_window": rows}


def markdown(table: dict[str, dict[str, float]]) -> str:
    """The table as Markdown (NaN shown as a dash)."""
    header = ("method", "meta", "kinematic", "interactive", "map", "minADE (m)", "collision", "offroad")
    rows = [(name, *(cell(r[c]) for c in COLUMNS)) for name, r in table.items()]
    return markdown_table((*header, "adv.–target collision"), rows)


@dataclass(frozen=True, kw_only=True)
class ClosedLoopSettings(SimulationSettings):
    """The closed-loop table's settings: one checkpoint, and the simulation settings every closed-loop table has."""

    checkpoint: Path


@EXPERIMENTS.register
class ClosedLoopExperiment(Experiment):
    """`langtraj experiment closed-loop`: realism, controllability and safety per method, one table per dataset."""

    name = "closed-loop"
    settings = ClosedLoopSettings

    def tables(self, settings: ClosedLoopSettings) -> dict[str, dict]:
        loaded = load_model(checkpoint_path(settings.checkpoint))
        results = {}
        for spec in settings.datasets:
            found, skipped = cases(spec, settings.windows)
            count = spec.rollouts or settings.rollouts
            config = SimConfig(rollouts=count, seed=settings.seed)
            result = run_experiment(loaded, found, config, settings.candidates, settings.steps)
            result["skipped_windows"] = skipped
            results[spec.name] = result
            print(
                f"\n{spec.name}: {len(found)} windows ({skipped} skipped: no prompt whose agents the model drives), "
                f"{count} rollouts, {settings.candidates} candidates per replan, K = {settings.steps}"
            )
            print(markdown(result["table"]))
        return results
