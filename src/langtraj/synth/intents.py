"""Drivers' decisions that their past does not reveal, made during a SUMO run (docs/data.md, 'Intents').

SUMO's drivers are regular: they take their turn lane early, keep their car-following profile and obey
right of way, so 1.1 s of history already tells where they go. Here each driver draws, from the shard
seed and its own id, decisions it takes later: which way to go at a junction from a lane that allows
several directions (chosen a few seconds before the stop line), a lane change at a random moment, a stop
in its lane or a pull-over to the kerb, a change of desired speed, and bold gap acceptance (it goes
before a foe it should yield to). `IntentController` applies them through libsumo step by step and
records each as an `AppliedDecision`; `decision_events` turns those into `decision` behaviour events
with what happened after them. Pure numpy below the controller, so the events are testable without SUMO.
"""

from __future__ import annotations

import re
import zlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any

import numpy as np

from langtraj.scenario.model import STEP_SECONDS, BehaviorEvent
from langtraj.synth.records import LaneChangeRecord, Track

KERB_MARGIN_M = 0.2
"""A pulled-over vehicle keeps this much room to the lane's outer edge (SUMO ignores a stop right on it)."""

WALKING_AREA = re.compile(r"^:.+_w\d+$")
CROSSING = re.compile(r"^:.+_c\d+$")
"""SUMO's ids of walking areas and crossings (internal edges of a junction: ':J_w0', ':J_c0')."""

COMFORTABLE_DECEL = 2.5
"""m/s^2: a decision must leave room to brake this hard (route choices, stops)."""


class Decision(StrEnum):
    """What a driver decides after its departure (the `decision` attribute of a `decision` event)."""

    ROUTE_CHOICE = "route_choice"  # the direction at the next junction, from a lane shared by several
    LANE_CHANGE = "lane_change"  # a lane change nobody asked for
    PULL_OVER = "pull_over"  # to the kerb of the rightmost lane, stop, go on
    STOP = "stop"  # stop in the lane (drop-off), go on
    SPEED_CHANGE = "speed_change"  # a new desired speed
    BOLD = "bold"  # accepts gaps it should leave: goes before foes it has to yield to
    PED_WAIT = "ped_wait"  # a pedestrian stands at the kerb a while before a crossing it could take


TIMED = (Decision.LANE_CHANGE, Decision.PULL_OVER, Decision.STOP, Decision.SPEED_CHANGE)
"""Decisions taken once, at a random moment after departure (a driver takes at most one of them)."""


@dataclass(frozen=True)
class IntentConfig:
    """How often drivers decide what, and the ranges of when and how much (shares are per driver).

    `route_choice` is the chance, at each approach to a junction on a lane that allows several
    directions, that the driver picks the direction afresh (uniformly among them) `route_decision_m`
    before the stop line. The timed decisions fall `delay_s` after departure; one that cannot be carried
    out then (no neighbour lane, too close to the lane's end) is retried every second for `retry_s`.
    """

    enabled: bool = True
    route_choice: float = 0.5
    route_decision_m: tuple[float, float] = (15.0, 60.0)
    lane_change: float = 0.12
    pull_over: float = 0.05
    stop: float = 0.03
    speed_change: float = 0.12
    bold: float = 0.15
    ped_wait: float = 0.3
    """Chance that a pedestrian reaching a crossing stands `ped_wait_s` at the kerb before taking it."""
    ped_wait_s: tuple[float, float] = (2.0, 10.0)
    delay_s: tuple[float, float] = (3.0, 45.0)
    retry_s: float = 30.0
    stop_duration_s: tuple[float, float] = (4.0, 20.0)
    stop_ahead_m: float = 25.0
    """A stop is placed at least this far ahead (plus the braking distance at 2.5 m/s^2)."""
    slower: tuple[float, float] = (0.5, 0.8)
    faster: tuple[float, float] = (1.2, 1.4)
    """Factors on the desired speed of a speed change (half the changes slow down, half speed up)."""
    min_lane_left_m: float = 40.0
    """A lane change or stop needs this much of the current lane still ahead."""
    no_stop_speed: float = 22.0
    """No stop or pull-over on lanes with at least this speed limit (m/s): motorways have no kerb."""

    def __post_init__(self) -> None:
        shares = (
            self.route_choice,
            self.lane_change,
            self.pull_over,
            self.stop,
            self.speed_change,
            self.bold,
            self.ped_wait,
        )
        if any(not 0.0 <= s <= 1.0 for s in shares):
            raise ValueError(f"IntentConfig shares must lie in [0, 1], got {shares}")
        if self.lane_change + self.pull_over + self.stop + self.speed_change > 1.0:
            raise ValueError("IntentConfig: the timed decision shares must add up to at most 1")


def driver_rng(seed: int, sumo_id: str) -> np.random.Generator:
    """The random stream of one driver: fixed by the shard seed and the driver's SUMO id, so it does not
    depend on the order in which drivers depart or are visited."""
    return np.random.default_rng([int(seed) & 0xFFFFFFFF, zlib.crc32(sumo_id.encode())])


@dataclass
class DriverPlan:
    """What one driver will decide: its timed decision and when (global step), bold or not, and the
    stream route choices are drawn from."""

    sumo_id: str
    rng: np.random.Generator
    timed: Decision | None = None
    due: int = 0
    give_up: int = 0
    bold: bool = False
    done: bool = False
    decided_edges: set[str] = field(default_factory=set)


def plan_driver(sumo_id: str, depart_step: int, seed: int, config: IntentConfig) -> DriverPlan:
    """Draw one driver's decisions (deterministic in seed and id)."""
    rng = driver_rng(seed, sumo_id)
    draws = rng.random(3)
    plan = DriverPlan(sumo_id, rng, bold=bool(draws[0] < config.bold))
    edges = np.cumsum([config.lane_change, config.pull_over, config.stop, config.speed_change])
    pick = int(np.searchsorted(edges, draws[1], side="right"))
    if pick < len(TIMED):
        plan.timed = TIMED[pick]
        lo, hi = config.delay_s
        plan.due = depart_step + round((lo + draws[2] * (hi - lo)) / STEP_SECONDS)
        plan.give_up = plan.due + round(config.retry_s / STEP_SECONDS)
    return plan


@dataclass(frozen=True)
class AppliedDecision:
    """A decision carried out at global `step` by SUMO vehicle `sumo_id`, with what it chose."""

    step: int
    sumo_id: str
    decision: Decision
    attributes: Mapping[str, Any]


# ---------------------------------------------------------------- applying decisions through libsumo


class IntentController:
    """Applies the drivers' decisions during a libsumo run (call `step` after every simulation step).

    `sinks` maps a vehicle class to the edges where its trips may end (the network's fringe), used to
    route a vehicle on after it picks a new direction.
    """

    def __init__(self, libsumo, config: IntentConfig, seed: int, sinks: Mapping[str, Sequence[str]]):
        self.ls = libsumo
        self.config = config
        self.seed = seed
        self.sinks = {k: tuple(v) for k, v in sinks.items()}
        self.plans: dict[str, DriverPlan] = {}
        self.applied: list[AppliedDecision] = []
        self.walkers: dict[str, tuple[np.random.Generator, set[str]]] = {}  # rng, walking areas decided on
        self.resume: dict[str, int] = {}  # pedestrian -> step to walk on

    def step(self, step: int) -> None:
        v = self.ls.vehicle
        for vid in self.ls.simulation.getDepartedIDList():
            plan = self.plans[vid] = plan_driver(vid, step, self.seed, self.config)
            if plan.bold:
                v.setImpatience(vid, 1.0)
                self._record(step, vid, Decision.BOLD, {})
        for vid in v.getIDList():
            plan = self.plans.get(vid)
            if plan is None:
                continue
            lane = v.getLaneID(vid)
            if not lane or lane.startswith(":"):
                continue
            if self.config.route_choice > 0:
                self._route_choice(step, vid, lane, plan)
            if plan.timed is not None and not plan.done and step >= plan.due and (step - plan.due) % 10 == 0:
                if step > plan.give_up:
                    plan.done = True
                else:
                    plan.done = self._timed(step, vid, lane, plan)
        if self.config.ped_wait > 0:
            self._pedestrians(step)

    def _pedestrians(self, step: int) -> None:
        """Pedestrians on a walking area whose next edge is a crossing may stand a while first."""
        p = self.ls.person
        for pid in p.getIDList():
            if self.resume.get(pid) == step:
                p.setSpeed(pid, -1.0)  # back to its type's speed
                del self.resume[pid]
                continue
            area = p.getRoadID(pid)
            if pid in self.resume or not WALKING_AREA.match(area):
                continue
            rng, decided = self.walkers.setdefault(pid, (driver_rng(self.seed, pid), set()))
            if area in decided:
                continue
            crossing = p.getNextEdge(pid)
            if not CROSSING.match(crossing):
                continue
            decided.add(area)
            if rng.random() >= self.config.ped_wait:
                continue
            seconds = round(float(rng.uniform(*self.config.ped_wait_s)), 1)
            p.setSpeed(pid, 0.0)
            self.resume[pid] = step + round(seconds / STEP_SECONDS)
            self._record(step, pid, Decision.PED_WAIT, {"crosswalk": crossing, "duration_s": seconds})

    def _record(self, step: int, vid: str, decision: Decision, attributes: dict[str, Any]) -> None:
        self.applied.append(AppliedDecision(step, vid, decision, attributes))

    def _allows(self, lane: str, vclass: str) -> bool:
        allowed = self.ls.lane.getAllowed(lane)
        return (not allowed or vclass in allowed) and vclass not in self.ls.lane.getDisallowed(lane)

    def _route_choice(self, step: int, vid: str, lane: str, plan: DriverPlan) -> None:
        v, ls = self.ls.vehicle, self.ls
        edge = v.getRoadID(vid)
        if edge in plan.decided_edges:
            return
        left = ls.lane.getLength(lane) - v.getLanePosition(vid)
        lo, hi = self.config.route_decision_m
        if left > hi:
            return
        plan.decided_edges.add(edge)  # one draw per approach, whatever it gives
        speed = v.getSpeed(vid)
        if (
            left < max(lo, speed * speed / (2 * COMFORTABLE_DECEL) + 5.0)
            or plan.rng.random() >= self.config.route_choice
        ):
            return  # too late to choose: the vehicle could not stop for foes of its new link
        vclass = v.getVehicleClass(vid)
        options: dict[str, str] = {}
        for link in ls.lane.getLinks(lane):
            target, direction = link[0], link[6]
            if direction not in ("t", "T") and self._allows(target, vclass):
                options.setdefault(direction, target.rsplit("_", 1)[0])
        if len(set(options.values())) < 2:
            return
        route, index = v.getRoute(vid), v.getRouteIndex(vid)
        planned_next = route[index + 1] if 0 <= index < len(route) - 1 else ""
        planned = next((d for d, e in options.items() if e == planned_next), "")
        directions = sorted(options)
        sinks = list(self.sinks.get(vclass, ()))
        for choice in plan.rng.permutation(directions):
            new_route = self._route_from(vid, options[str(choice)], sinks, plan.rng)
            if new_route:
                v.setRoute(vid, [edge, *new_route])
                self._record(
                    step,
                    vid,
                    Decision.ROUTE_CHOICE,
                    {
                        "direction": str(choice),
                        "options": "".join(directions),
                        "planned": planned,
                        "changed": str(choice) != planned,
                        "lane": lane,
                        "next_edge": options[str(choice)],
                    },
                )
                return

    def _route_from(self, vid: str, start: str, sinks: list[str], rng: np.random.Generator) -> list[str]:
        vtype = self.ls.vehicle.getTypeID(vid)
        for sink in rng.permutation(sinks) if sinks else ():
            try:
                edges = list(self.ls.simulation.findRoute(start, str(sink), vType=vtype).edges)
            except self.ls.TraCIException:
                continue
            if edges and edges[0] == start:
                return edges
        return []

    def _timed(self, step: int, vid: str, lane: str, plan: DriverPlan) -> bool:
        """Carry out the driver's timed decision now if it can be; True when done."""
        v, ls, cfg = self.ls.vehicle, self.ls, self.config
        left = ls.lane.getLength(lane) - v.getLanePosition(vid)
        speed = v.getSpeed(vid)
        if plan.timed == Decision.SPEED_CHANGE:
            lo, hi = cfg.slower if plan.rng.random() < 0.5 else cfg.faster
            old = v.getSpeedFactor(vid)
            new = round(old * float(plan.rng.uniform(lo, hi)), 3)
            v.setSpeedFactor(vid, new)
            self._record(step, vid, Decision.SPEED_CHANGE, {"from_factor": old, "to_factor": new, "speed": speed})
            return True
        if left < cfg.min_lane_left_m or speed < 2.0:
            return False
        edge = v.getRoadID(vid)
        index = v.getLaneIndex(vid)
        if plan.timed == Decision.LANE_CHANGE:
            best = {int(b[0].rsplit("_", 1)[1]): b for b in v.getBestLanes(vid) if b[0].rsplit("_", 1)[0] == edge}
            targets = [i for i in (index - 1, index + 1) if i in best and best[i][4]]  # [4]: allows continuation
            if not targets:
                return False
            target = int(plan.rng.choice(targets))
            v.changeLane(vid, target, 5.0)
            direction = "left" if target > index else "right"
            self._record(step, vid, Decision.LANE_CHANGE, {"direction": direction, "from_lane": lane})
            return True
        if ls.lane.getMaxSpeed(lane) >= cfg.no_stop_speed:
            return False
        vclass = v.getVehicleClass(vid)
        if plan.timed == Decision.PULL_OVER:
            lanes = [i for i in range(ls.edge.getLaneNumber(edge)) if self._allows(f"{edge}_{i}", vclass)]
            target = lanes[0] if lanes else index
        else:
            target = index
        ahead = cfg.stop_ahead_m + speed * speed / (2 * COMFORTABLE_DECEL)
        position = v.getLanePosition(vid) + ahead
        if position > ls.lane.getLength(lane) - 5.0:
            return False
        duration = round(float(plan.rng.uniform(*cfg.stop_duration_s)), 1)
        try:
            v.setStop(vid, edge, pos=position, laneIndex=target, duration=duration)
            if plan.timed == Decision.PULL_OVER:
                width = ls.lane.getWidth(f"{edge}_{target}")
                v.setStopParameter(vid, 0, "posLat", str(-max(width - v.getWidth(vid) - KERB_MARGIN_M, 0.0) / 2))
        except self.ls.TraCIException:
            return False
        self._record(
            step, vid, plan.timed, {"edge": edge, "lane_index": target, "position": position, "duration_s": duration}
        )
        return True


# ---------------------------------------------------------------- events


ROUTE_HORIZON_S = 15.0
"""A route choice counts as carried out when the vehicle reaches the chosen edge within this time."""

LANE_CHANGE_HORIZON_S = 8.0
"""A requested lane change counts when SUMO switches lanes for TraCI within this time."""

STOP_HORIZON_S = 30.0
"""A stop or pull-over counts when the vehicle stands within this time."""

SPEED_CHANGE_SPAN_S = 6.0
"""The event of a speed change spans this long (the new desired speed holds for the rest of the trip)."""

STOPPED_SPEED = 0.3


def _first(mask: np.ndarray) -> int | None:
    hits = np.flatnonzero(mask)
    return int(hits[0]) if len(hits) else None


def _outcome(
    applied: AppliedDecision,
    track: Track,
    lane_names: Sequence[str],
    changes: Sequence[LaneChangeRecord],
) -> tuple[int, dict[str, Any]]:
    """One past the last step of what the decision led to, and attributes of it (`executed` and more)."""
    step, d = applied.step, applied.decision
    here = track.local(step)
    if d == Decision.ROUTE_CHOICE:
        horizon = here + round(ROUTE_HORIZON_S / STEP_SECONDS)
        lanes = track.lane[here:horizon]
        edges = np.array([lane_names[i].rsplit("_", 1)[0] if i >= 0 else "" for i in lanes])
        reached = _first(edges == applied.attributes["next_edge"])
        if reached is None:
            return step + 1, {"executed": False}
        return step + reached + 1, {"executed": True, "junction_exit_step": step + reached}
    if d == Decision.LANE_CHANGE:
        horizon = step + round(LANE_CHANGE_HORIZON_S / STEP_SECONDS)
        for record in changes:
            if record.tag == "change" and step <= record.step <= horizon and "traci" in record.reason:
                return record.step + 1, {"executed": True, "change_step": record.step, "to_lane": record.to_lane}
        return step + 1, {"executed": False}
    if d in (Decision.STOP, Decision.PULL_OVER, Decision.PED_WAIT):
        horizon = here + round(STOP_HORIZON_S / STEP_SECONDS)
        standing = track.speed[here:horizon] <= STOPPED_SPEED
        stopped = _first(standing)
        if stopped is None:
            return step + 1, {"executed": False}
        moving = _first(track.speed[here + stopped :] > STOPPED_SPEED)
        end = track.stop if moving is None else step + stopped + moving
        return end, {"executed": True, "stopped_step": step + stopped}
    if d == Decision.SPEED_CHANGE:
        return min(track.stop, step + round(SPEED_CHANGE_SPAN_S / STEP_SECONDS)), {"executed": True}
    return step + 1, {"executed": True}


def decision_events(
    applied: Sequence[AppliedDecision],
    tracks: Mapping[str, Track],
    lane_names: Sequence[str],
    lane_changes: Sequence[LaneChangeRecord],
) -> list[BehaviorEvent]:
    """A `decision` event per carried-out decision of a recorded vehicle (bold gap acceptance is a trait,
    not an event: it shows in `go_first` events). Attributes: `decision`, `decision_step`, what was chosen,
    and `executed` (whether the vehicle did it within the horizon of its kind)."""
    by_vehicle: dict[str, list[LaneChangeRecord]] = {}
    for record in lane_changes:
        by_vehicle.setdefault(record.sumo_id, []).append(record)
    events = []
    for a in applied:
        track = tracks.get(a.sumo_id)
        if a.decision == Decision.BOLD or track is None or not track.start <= a.step < track.stop:
            continue
        end, outcome = _outcome(a, track, lane_names, by_vehicle.get(a.sumo_id, ()))
        attributes = {"decision": str(a.decision), "decision_step": a.step, **dict(a.attributes), **outcome}
        events.append(BehaviorEvent("decision", track.track_id, a.step, max(end, a.step + 1), -1, attributes))
    return events
