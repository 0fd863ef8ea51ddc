"""Traffic faults: collisions and off-road among the other agents of an episode (the simulated ones, not the ego),
and whether the ego's failure follows from one (docs/testing.md, 'Traffic faults').

The events are `sim.failures.classify_failures` of the episode as played with the ego left out (made invalid, so
not a sim agent): each other agent's first contact with another agent and each other vehicle's first off-road step,
as the realism table's collision and off-road rates count them (`metrics.controllability`), each with its cause. A
pair's two first contacts are one collision. An episode cut short is held at its last step. Not counted as faults
(`NOT_FAULTS`): two boxes already touching in the log at the start, people walking together, a car past the map's
end, a vehicle already off the road at the start (its box at the current step, by the same road-edge distance), and
any event of an agent that had touched the ego before it (`ego`: the ego was part of it). The ego's own
contacts are the step info's (`figures.collisions`), never traffic faults.

The ego's failure follows a traffic fault (`follows_traffic_fault`) when one of its failing events (each collision,
each failed criterion at its step; progress, speed limit and comfort, which have no one step, over the whole
episode) involves an agent that had a fault at or before that step, or comes at most `FOLLOW_S` after a fault at most
`NEAR_M` from the ego (a criterion without a step: a fault that near at any time), unless it is a collision with a
prompted agent or the adversary: the case's own failure, which follows a fault only when that agent had one.
"""

from __future__ import annotations

from collections.abc import Collection, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from langtraj.angles import wrap_angle
from langtraj.metrics.features import OFFROAD_THRESHOLD
from langtraj.metrics.road import distance_to_road_edge
from langtraj.rollouts.agents import sim_agent_indices
from langtraj.rollouts.container import Rollouts
from langtraj.scenario.model import FUTURE_STEPS, STEP_SECONDS, Scenario
from langtraj.scenario.types import StateField
from langtraj.sim.failures import FailureScene, classify_failures

FOLLOW_S = 3.0
"""An ego failure at most this long after a traffic fault near it follows from it (s)."""
NEAR_M = 20.0
"""... when the fault's agents were at most this far from the ego's centre at the fault's step (m)."""
NOT_FAULTS = {
    "log_overlap": "touching in the log at the start",
    "pedestrian_group": "walking together",
    "map_ends": "past the map's end",
    "offroad_at_start": "off the road at the start",
}
"""Causes of events listed but not counted as traffic faults (`sim.failures` causes, and off-road at the start)."""
SHOWN = 5
"""Events named per list in a line of text."""
STEP_OF = {
    "no_at_fault_collision": ("first_at_fault_step", "at_fault_with"),
    "no_collision": ("first_collision_step", "collided_with"),
    "no_offroad": ("first_offroad_step", None),
    "min_ttc": ("min_ttc_step", None),
    "no_red_light": ("first_red_light_step", None),
    "no_wrong_way": ("first_wrong_way_step", None),
}
"""A failed criterion's step and partners among the figures (`verdict.episode_figures`); the others have none."""


@dataclass(frozen=True)
class TrafficEvent:
    """A collision between two other agents (`agent`, `other`) or one's off-road (`other` None), first at `step`
    (1-based, as the step info's), of `cause` (`sim.failures`, or "offroad_at_start"); `ego`: one of its agents
    had touched the ego before it; `ego_distance_m`: its agents' nearest centre to the ego's then (None
    without an ego in the scene)."""

    kind: str
    agent: int
    other: int | None
    step: int
    cause: str
    ego: bool
    ego_distance_m: float | None

    @property
    def agents(self) -> tuple[int, ...]:
        return (self.agent,) if self.other is None else (self.agent, self.other)

    @property
    def time(self) -> float:
        return round(self.step * STEP_SECONDS, 1)

    @property
    def fault(self) -> bool:
        """A traffic fault: the ego not part of it, nor a cause of `NOT_FAULTS`."""
        return not self.ego and self.cause not in NOT_FAULTS

    def to_json(self) -> dict[str, Any]:
        distance = None if self.ego_distance_m is None else round(self.ego_distance_m, 1)
        return {
            "kind": self.kind,
            "agent": self.agent,
            "with": self.other,
            "step": self.step,
            "time": self.time,
            "cause": self.cause,
            "ego": self.ego,
            "ego_distance_m": distance,
            "fault": self.fault,
        }


@dataclass(frozen=True)
class Traffic:
    """An episode's traffic events (step order) and whether off-road was measured (the map has road edges)."""

    events: tuple[TrafficEvent, ...]
    offroad_measured: bool

    def faults(self, kind: str | None = None) -> list[TrafficEvent]:
        return [e for e in self.events if e.fault and (kind is None or e.kind == kind)]

    def to_json(self) -> dict[str, Any]:
        """results.json's `traffic`: the counts of faults, then every event."""
        return {
            "collisions": len(self.faults("collision")),
            "offroad": len(self.faults("offroad")),
            "faults": len(self.faults()),
            "offroad_measured": self.offroad_measured,
            "events": [e.to_json() for e in self.events],
        }


@dataclass(frozen=True)
class EgoFailure:
    """One failing event of the ego: what (a criterion's reason, or a collision), its step (None: the whole
    episode) and the agents it involves."""

    what: str
    step: int | None
    partners: tuple[int, ...] = ()


def played_rollouts(scene: Scenario) -> Rollouts:
    """The played steps of `scene`'s sim agents as one rollout of `FUTURE_STEPS`, each agent held at its last
    valid state (an episode cut short: at its last step)."""
    c, rows = scene.current_index, sim_agent_indices(scene)
    states = scene.agents.states[rows, c:].astype(np.float64)
    valid = scene.agents.valid[rows, c:]
    latest = np.maximum.accumulate(np.where(valid, np.arange(valid.shape[1]), 0), axis=1)
    held = np.take_along_axis(states, latest[..., None], axis=1)[:, 1:]
    future = held[:, np.minimum(np.arange(FUTURE_STEPS), held.shape[1] - 1)]
    return Rollouts(
        object_id=scene.agents.ids[rows],
        x=future[None, ..., StateField.X],
        y=future[None, ..., StateField.Y],
        z=future[None, ..., StateField.Z],
        heading=wrap_angle(future[None, ..., StateField.HEADING]),
        scenario_id=scene.scenario_id,
    )


def _first_touches(touched: Sequence[Sequence[int]]) -> dict[int, int]:
    """Per agent, the first step (1-based) its box overlapped the ego's (`StepRecord.collided_with`)."""
    first: dict[int, int] = {}
    for k, ids in enumerate(touched):
        for i in ids:
            first.setdefault(int(i), k + 1)
    return first


def _offroad_at_start(scene: FailureScene, rows: list[int]) -> set[int]:
    """The rows among `rows` whose box at the current step is off the road (the off-road rate's distance)."""
    edges = scene.scene_map.road_edges
    if edges is None or not rows:
        return set()
    s = scene.scenario.agents.states[rows, scene.scenario.current_index].astype(np.float64)
    f = StateField
    fields = (f.X, f.Y, f.Z, f.HEADING, f.LENGTH, f.WIDTH, f.HEIGHT)
    dist = distance_to_road_edge(edges, *(s[:, k] for k in fields), np.ones(len(rows), bool))
    return {r for r, d in zip(rows, dist, strict=True) if d > OFFROAD_THRESHOLD}


def traffic_faults(played: Scenario, ego: int, touched: Sequence[Sequence[int]]) -> Traffic:
    """The traffic events of an episode: `played` (the env's `played()`), the ego's track id and the ids its box
    overlapped at each step (`StepRecord.collided_with`)."""
    agents = played.agents
    ids = [int(i) for i in agents.ids]
    ego_row = ids.index(int(ego)) if int(ego) in ids else None
    valid = agents.valid.copy()
    if ego_row is not None:
        valid[ego_row] = False  # the ego left out: not a sim agent
    others = replace(played, agents=replace(agents, valid=valid))
    steps = min(played.num_steps - played.current_index - 1, FUTURE_STEPS)
    if steps < 1 or len(sim_agent_indices(others)) < 2:
        return Traffic((), True)
    rollouts = played_rollouts(others)
    scene = FailureScene.build(others)
    report = classify_failures(others, rollouts, scene=scene)
    first_touch = _first_touches(touched)
    column = {int(i): k for k, i in enumerate(rollouts.object_id)}
    at_start = _offroad_at_start(scene, [ids.index(e.agent_id) for e in report.events if e.kind == "offroad"])
    found: dict[tuple[str, tuple[int, ...]], TrafficEvent] = {}
    for e in sorted(report.events, key=lambda e: e.step):
        step = min(e.step, steps - 1) + 1
        pair = (e.agent_id,) if e.partner_id is None else tuple(sorted((e.agent_id, e.partner_id)))  # smaller first
        if (e.kind, pair) in found:
            continue
        cause = "offroad_at_start" if e.kind == "offroad" and ids.index(e.agent_id) in at_start else e.cause
        distance = None
        if ego_row is not None:
            where = agents.states[ego_row, played.current_index + step, : StateField.Y + 1].astype(np.float64)
            cols = [column[a] for a in pair]
            xy = np.stack([rollouts.x[0, cols, step - 1], rollouts.y[0, cols, step - 1]], -1).astype(np.float64)
            distance = float(np.linalg.norm(xy - where, axis=-1).min())
        touched_ego = any(first_touch.get(a, step) < step for a in pair)
        other = pair[1] if len(pair) > 1 else None
        found[(e.kind, pair)] = TrafficEvent(e.kind, pair[0], other, step, cause, touched_ego, distance)
    events = sorted(found.values(), key=lambda e: (e.step, e.kind, e.agents))
    return Traffic(tuple(events), scene.scene_map.road_edges is not None)


def ego_failures(figures: dict[str, Any], criteria: Sequence[dict[str, Any]]) -> list[EgoFailure]:
    """The ego's failing events: each failed criterion (`CriterionResult.to_json()`) at its step, and each of its
    collisions (`figures["collisions"]`), whether or not it failed a criterion."""
    out = []
    for c in criteria:
        if c["passed"]:
            continue
        step_key, with_key = STEP_OF.get(c["name"], (None, None))
        step = figures.get(step_key) if step_key else None
        partners = tuple(int(i) for i in figures.get(with_key, [])) if with_key else ()
        out.append(EgoFailure(c["reason"] or c["name"], step, partners))
    for contact in figures.get("collisions", []):
        what = f"collision with {contact['with']} at step {contact['step']}"
        out.append(EgoFailure(what, contact["step"], (int(contact["with"]),)))
    return out


def describe(event: TrafficEvent | dict[str, Any]) -> str:
    """`@12-@15 at 4.2 s` (a collision) or `@40 at 6.1 s` (off-road)."""
    e = event.to_json() if isinstance(event, TrafficEvent) else event
    who = f"@{e['agent']}" + ("" if e["with"] is None else f"-@{e['with']}")
    return f"{who} at {e['time']:.1f} s"


def follows_traffic_fault(traffic: Traffic, failures: Sequence[EgoFailure], staged: Collection[int] = ()) -> str | None:
    """Why the first of the ego's `failures` that follows a traffic fault does (the module docstring's rule), in one
    line; None when none does. A failure with one of the `staged` agents (prompted, or the adversary) is the case's
    own: it follows a fault only when that agent had one."""
    faults = traffic.faults()
    for failure in sorted(failures, key=lambda f: (f.step is None, f.step or 0)):
        s = failure.step
        own = bool(set(failure.partners) & set(staged))
        for fault in faults:
            before = s is None or fault.step <= s
            what = f"{fault.kind} {describe(fault)}"
            involved = set(fault.agents) & set(failure.partners)
            if before and involved:
                return f"{failure.what} follows @{min(involved)}'s traffic fault: {what}"
            near = not own and fault.ego_distance_m is not None and fault.ego_distance_m <= NEAR_M
            if near and before and (s is None or (s - fault.step) * STEP_SECONDS <= FOLLOW_S + 1e-9):
                after = "" if s is None else f", {(s - fault.step) * STEP_SECONDS:.1f} s before"
                distance = f"{fault.ego_distance_m:.0f} m from the ego{after}"
                return f"{failure.what} follows a traffic fault {distance}: {what}"
    return None


def _listed(events: Sequence[dict[str, Any]]) -> str:
    shown = ", ".join(describe(e) for e in events[:SHOWN])
    return shown + (f", ... ({len(events)} in all)" if len(events) > SHOWN else "")


def traffic_text(traffic: dict[str, Any]) -> str:
    """results.json's `traffic` in words: `3 collisions among other agents (@12-@15 at 4.2 s, ...), 1 off-road (@40
    at 6.1 s); not counted: ...`."""
    events = traffic.get("events", [])
    collisions = [e for e in events if e["fault"] and e["kind"] == "collision"]
    offroad = [e for e in events if e["fault"] and e["kind"] == "offroad"]
    parts = []
    if collisions:
        plural = "s" if len(collisions) != 1 else ""
        parts.append(f"{len(collisions)} collision{plural} among other agents ({_listed(collisions)})")
    if offroad:
        parts.append(f"{len(offroad)} off-road ({_listed(offroad)})")
    line = ", ".join(parts) if parts else "no collision or off-road among other agents"
    if not traffic.get("offroad_measured", True):
        line += " (off-road not measured: no road edges)"
    aside = [e for e in events if e["ego"]]
    rest = []
    if aside:
        rest.append(f"{len(aside)} after touching the ego ({_listed(aside)})")
    for cause, words in NOT_FAULTS.items():
        count = sum(1 for e in events if not e["ego"] and e["cause"] == cause)
        if count:
            rest.append(f"{count} {words}")
    return line + (f"; not counted: {', '.join(rest)}" if rest else "")
