"""Judging a run of a job: per prompt and rollout whether the labelers find it followed, per sim agent and
rollout whether it collides or leaves the road, the WOSAC realism of the rollouts where the scene logs its
future, the rollouts themselves as the page replays them, and the prompted agents' speed and distance to their
targets over time as it plots them (`studio.series`; docs/studio.md, 'GET /api/jobs/{id}').

A prompt is judged as the suites judge it (`interdrive.behaviours.verdict`): its reading's `PromptReading.followed`
among the facts the labelers find in the rollout (`AdherenceChecker.facts` of `rollout_scenario`), as the
simulation's own candidate judge counts it (docs/simulation.md, 'Prompts that steer'), and for the safety-critical
pair behaviours by their numbers too, asked beside realised (docs/testing.md, 'Judged by numbers')."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from langtraj.errors import InputError
from langtraj.interdrive.adherence import AdherenceChecker
from langtraj.interdrive.behaviours.verdict import judge_reading
from langtraj.interdrive.reader import PromptReading
from langtraj.metrics.controllability import collision_events, offroad_first_steps
from langtraj.metrics.flow import traffic_flow
from langtraj.metrics.instruction_following import rollout_scenario
from langtraj.metrics.wosac import evaluate_scenario
from langtraj.rollouts.agents import evaluated_agent_indices
from langtraj.rollouts.container import Rollouts
from langtraj.scenario.drivable import road_edges_derived_from
from langtraj.scenario.model import Scenario
from langtraj.scenario.types import AgentType
from langtraj.sim.parked import parked_in_history
from langtraj.sim.staging import starts_of
from langtraj.studio.series import prompted_series

REALISM_FIELDS = {
    "meta_metric": "metametric",
    "kinematic": "kinematic_metrics",
    "interactive": "interactive_metrics",
    "map_based": "map_based_metrics",
    "collision_rate": "simulated_collision_rate",
    "offroad_rate": "simulated_offroad_rate",
}
"""The WOSAC figures a run reports (name in the result: `ScenarioMetrics` field)."""
FLOW_FIELDS = {
    "moving_vehicles_speed_vs_log": "speed_ratio",
    "moving_vehicles_end_stopped": "stopped",
    "moving_vehicles_end_stopped_in_log": "stopped_log",
}
"""The flow figures a run reports (name in the result: `metrics.flow.FlowResult.as_dict` key)."""


def judge_prompts(
    scenario: Scenario,
    rollouts: Rollouts,
    texts: Sequence[str],
    readings: Sequence[PromptReading],
    checker: AdherenceChecker | None,
    report: dict[str, Any] | None = None,
) -> list[dict[str, Any]]:
    """Per prompt: its text, agents and behaviour, and per rollout the one verdict of the suites and the studio
    (`behaviours.verdict.judge_reading`): whether it follows it, why not, and for a behaviour judged by numbers the
    asked and realised numbers (the labelers run once per rollout); a behaviour staged at its trigger is judged from
    when it started in that rollout (the simulation's `report`, `sim.staging.starts_of`)."""
    present = {int(i) for i in rollouts.object_id}
    judged = [r.unjudged(present) is None for r in readings]
    played, found = [], []
    if any(judged):
        if checker is None:
            raise ValueError("prompts to judge need an adherence checker")
        played = [rollout_scenario(scenario, rollouts, r) for r in range(rollouts.num_rollouts)]
        found = [checker.facts(p) for p in played]
    out = []
    starts = [starts_of(report or {}, r) for r in range(len(played))]
    for text, reading, judge in zip(texts, readings, judged, strict=True):
        verdicts = []
        if judge:
            for p, f, start in zip(played, found, starts, strict=True):
                verdicts.append(judge_reading(reading, p, f, start.get(reading.agent) if reading.agent else None))
        out.append(
            {
                "text": text,
                "agent": reading.agent,
                "other": reading.other,
                "behaviour": None if reading.behaviour is None else reading.behaviour.value,
                "followed": [v.followed for v in verdicts] if judge else [None] * rollouts.num_rollouts,
                "why": [v.why for v in verdicts] if judge else [None] * rollouts.num_rollouts,
                "measures": [[m.to_json() for m in v.measures] for v in verdicts]
                if judge
                else [[] for _ in range(rollouts.num_rollouts)],
            }
        )
    return out


def agent_outcomes(scenario: Scenario, rollouts: Rollouts) -> list[dict[str, Any]]:
    """Per rollout agent: whether it collides with another rollout agent in each rollout (`collision_flags`, read
    off its events rather than computed twice), each first contact with
    its step (0: the first simulated one) and partner (`collision_events`, the same signed distance as the realism
    table's collision rate), whether WOSAC scores it (`evaluated`: the realism rates are over these agents alone),
    whether it stands still through its history (`parked`), and whether it leaves the road (vehicles only; null for
    pedestrians, cyclists and others, and where the map has no road edges: not measured) and at which step it first
    does in each rollout it does (`offroads`, as `metrics.controllability.offroad_first_steps`)."""
    ids = [int(i) for i in rollouts.object_id]
    column = {i: k for k, i in enumerate(ids)}
    collided = np.zeros((rollouts.num_rollouts, len(ids)), bool)  # [R, A]: `collision_flags`, from its events
    contacts: dict[int, list[dict[str, int]]] = {i: [] for i in ids}
    for event in collision_events(scenario, rollouts):
        collided[event.rollout, column[event.agent]] = True
        contacts[event.agent].append({"rollout": event.rollout, "step": event.step, "with": event.other})
    evaluated = {int(i) for i in scenario.agents.ids[evaluated_agent_indices(scenario)]}
    parked = {int(i) for i in scenario.agents.ids[parked_in_history(scenario)]}
    offroad: dict[int, list[bool]] = {}
    leaves: dict[int, list[dict[str, int]]] = {}
    types = scenario.agents.types[[scenario.agents.index_of(i) for i in ids]]
    if (types == AgentType.VEHICLE).any():
        try:
            found, first = offroad_first_steps(scenario, rollouts)
        except InputError:  # no road edges: offroad cannot be measured
            found, first = np.zeros(0, np.int64), np.zeros((rollouts.num_rollouts, 0), np.int64)
        for k, i in enumerate(found):
            offroad[int(i)] = (first[:, k] >= 0).tolist()
            leaves[int(i)] = [{"rollout": r, "step": int(s)} for r, s in enumerate(first[:, k]) if s >= 0]
    nothing = [None] * rollouts.num_rollouts
    return [
        {
            "id": i,
            "collision": collided[:, k].tolist(),
            "collisions": contacts[i],
            "offroad": offroad.get(i, nothing),
            "offroads": leaves.get(i, []),
            "evaluated": i in evaluated,
            "parked": i in parked,
        }
        for k, i in enumerate(ids)
    ]


def realism(scenario: Scenario, rollouts: Rollouts) -> dict[str, Any]:
    """WOSAC figures of the rollouts (2025 configuration), over the agents WOSAC evaluates (`evaluated`, their
    count), and the flow of the vehicles moving at the start against their log (`metrics.flow`: `FLOW_FIELDS`); all
    null, with the reason, where the scene does not log the 80 future steps or has no agent to score."""
    evaluated = len(evaluated_agent_indices(scenario))
    flow = traffic_flow(scenario, rollouts).as_dict()
    flows = {name: _finite(flow[key]) for name, key in FLOW_FIELDS.items()}
    try:
        metrics = evaluate_scenario(scenario, rollouts).to_dict()
    except InputError as exc:
        return {name: None for name in REALISM_FIELDS} | flows | {"note": str(exc), "evaluated": evaluated}
    return (
        {name: _finite(metrics[key]) for name, key in REALISM_FIELDS.items()}
        | flows
        | {
            "note": None,
            "evaluated": evaluated,
        }
    )


def road_edges(scenario: Scenario) -> str | None:
    """What off-road is measured against: "map" (its own road edges), "derived from ..." (edges derived where the
    map has none, as nuScenes'), or None (nothing to measure against: off-road is not measured)."""
    if scenario.road_map.road_edges:
        return "map"
    derived = road_edges_derived_from(scenario)
    return f"derived from {derived}" if derived else None


def table_rates(agents: Sequence[dict[str, Any]]) -> dict[str, float | None]:
    """The per-agent table's own rates: the share of (rollout, agent) pairs colliding and, of the vehicles
    measured, leaving the road, over every agent and over the evaluated ones (which is WOSAC's collision rate)."""

    def share(rows: Sequence[dict[str, Any]], key: str) -> float | None:
        flags = [f for row in rows for f in row[key] if f is not None]
        return round(sum(flags) / len(flags), 4) if flags else None

    evaluated = [a for a in agents if a["evaluated"]]
    return {
        "collision_all": share(agents, "collision"),
        "collision_evaluated": share(evaluated, "collision"),
        "offroad_all": share(agents, "offroad"),
        "offroad_evaluated": share(evaluated, "offroad"),
    }


def rollouts_json(rollouts: Rollouts) -> list[dict[str, dict[str, list[float]]]]:
    """Per rollout, per agent (track id as text), its 80 simulated x, y (metres, to the
    centimetre) and headings (radians, to the milliradian)."""
    ids = [str(int(i)) for i in rollouts.object_id]
    out = []
    for r in range(rollouts.num_rollouts):
        one = {}
        for name, digits in (("x", 2), ("y", 2), ("heading", 3)):
            values = np.round(getattr(rollouts, name)[r].astype(np.float64), digits)
            one[name] = dict(zip(ids, values.tolist(), strict=True))
        out.append(one)
    return out


def run_json(
    scenario: Scenario,
    rollouts: Rollouts,
    texts: Sequence[str],
    readings: Sequence[PromptReading],
    checker: AdherenceChecker | None,
    report: dict[str, Any],
    seconds: float,
    aims: Sequence[dict[str, Any]] | None = None,
) -> dict[str, Any]:
    """The RUN object of a job's result; its `series` are those of the agents the prompts name (`agent` and
    `other`), toward `aims` (default: the report's targets; a run without the prompts is measured to the prompted
    run's, so the page can show how far the agent gets without being asked)."""
    prompt = report.get("prompt") or {}
    agents = agent_outcomes(scenario, rollouts)
    targets = list(prompt.get("targets") or [])
    named = [i for r in readings for i in (r.agent, r.other) if i is not None]
    return {
        "rollouts": rollouts_json(rollouts),
        "prompts": judge_prompts(scenario, rollouts, texts, readings, checker, report),
        "agents": agents,
        "rates": table_rates(agents),
        "road_edges": road_edges(scenario),
        "realism": realism(scenario, rollouts),
        "targets": targets,
        "series": prompted_series(scenario, rollouts, targets if aims is None else aims, named),
        "warnings": list(report.get("prompt_warnings") or []),
        "seconds": round(seconds, 2),
    }


def _finite(value: Any) -> float | None:
    return None if not isinstance(value, int | float) or not math.isfinite(value) else round(float(value), 4)
