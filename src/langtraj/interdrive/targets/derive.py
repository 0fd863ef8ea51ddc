"""Deriving a target: `derive_target` asks the behaviour's own module (`interdrive.behaviours`) where it takes an
agent at the scene's current step, and `stop_after` adds a stop past a manoeuvre ("turns left and then stops").

Only the current step and the past are read (never the logged future), so a simulation may use the target.
See docs/interdrive.md ('Targets and feasibility').
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace

import numpy as np

from langtraj.errors import InputError
from langtraj.interdrive.behaviour import BEHAVIOURS, Behaviour
from langtraj.interdrive.behaviours.base import kind
from langtraj.interdrive.targets.config import CounterfactualConfig
from langtraj.interdrive.targets.context import (
    COMFORT_DECELERATION,
    HORIZON_S,
    LANE_CHANGE_MIN_M,
    TargetContext,
)
from langtraj.interdrive.targets.target import BehaviourTarget, TargetUnavailable
from langtraj.interdrive.taxonomy import LABELS_BY_KEY
from langtraj.polylines import arc_lengths
from langtraj.roads import MapIndex
from langtraj.scenario.model import Scenario

STOP_AFTER_M = 2.0
"""How far past where a manoeuvre is done a stop asked after it lies (m): a turn is done 5 m past the junction's exit,
so its stop lies 7 m past the exit, the car wholly out of the junction."""
LANE_CHANGE_DONE_S = 4.0
"""When a lane change is done (s): its steering holds the agent in the new lane from then (`guidance.steering`)."""
STOP_AFTER_BY_S = HORIZON_S - 1.0
"""The latest a stop asked after a manoeuvre may begin to stand (s): the labelers see a stop of 1 s or more."""
STOP_AFTER_MIN_SPEED = 3.0
"""The speed (m/s) a slower agent is taken to set off at to reach a stop past its manoeuvre."""


def derive_target(
    scenario: Scenario,
    track_id: int,
    behaviour: Behaviour,
    index: MapIndex,
    *,
    other_id: int | None = None,
    config: CounterfactualConfig | None = None,
    gap: float | None = None,
    deceleration: float | None = None,
    routes: Mapping[int, np.ndarray] | None = None,
) -> BehaviourTarget:
    """The target of `behaviour` for `track_id` at the scenario's current step (see the module docstring;
    `target_of`), the agents with a known route (`routes`, `TargetContext`) read on it. Raises `TargetUnavailable`
    (an InputError) naming the agent, the behaviour and the reason where the map gives none: then the behaviour is
    not feasible there (`feasibility`)."""
    ctx = TargetContext(scenario, index, config, routes)
    return target_of(ctx, track_id, behaviour, other_id, gap, deceleration)


def target_of(
    ctx: TargetContext,
    track_id: int,
    behaviour: Behaviour,
    other_id: int | None = None,
    gap: float | None = None,
    deceleration: float | None = None,
) -> BehaviourTarget:
    """The target of `behaviour` for `track_id` in the scene `ctx` reads (toward `other_id` for a pair behaviour; a
    cut-in `gap` m ahead of it; a braking lead at `deceleration` m/s^2): the behaviour's own
    (`BehaviourKind.target`, parameters it is not given at their defaults), or `TargetUnavailable` with the reason."""
    behaviour_kind = kind(behaviour, where="target")
    spec = behaviour_kind.spec
    if spec.is_pair and other_id is None:
        raise InputError(f"behaviour {behaviour!s} needs another agent", where="target")
    agent = ctx.agent(track_id, behaviour)
    if spec.label is not None and agent.kind not in LABELS_BY_KEY[spec.label].applies_to:
        reason = f"the labelers give {spec.label!r} to no {agent.kind.name.lower()}"
        raise TargetUnavailable(track_id, behaviour, "undecided", reason)
    other = None if other_id is None else ctx.agent(int(other_id), behaviour)
    figures = {"metres": gap, "deceleration": deceleration}
    asked = {p.name: p.default if figures[p.reads] is None else figures[p.reads] for p in behaviour_kind.parameters}
    return behaviour_kind.target(ctx, agent, other, asked)


def stop_after(target: BehaviourTarget) -> BehaviourTarget:
    """A manoeuvre's target (a turn or a lane change) and then a stop past it: along its path, `STOP_AFTER_M` past
    where the manoeuvre is done (a turn: its goal past the junction's exit; a lane change: where its lead-in joins the
    new lane, and no sooner than its steering holds it there, `LANE_CHANGE_DONE_S` at its speed), and no nearer than
    braking at `COMFORT_DECELERATION` brings it to rest; standing (`settled_s`) once it gets there driving on at its
    speed (at least `STOP_AFTER_MIN_SPEED`) and then braking at that deceleration, which must be by
    `STOP_AFTER_BY_S`; else `TargetUnavailable` (infeasible)."""
    spec = BEHAVIOURS[target.behaviour]
    v = target.current_speed
    if spec.is_turn and target.station_of_goal is not None:
        done, what = target.station_of_goal, "the junction"
    elif spec.is_lane_change:
        done, what = max(target.joins_m or 0.0, LANE_CHANGE_DONE_S * v, LANE_CHANGE_MIN_M), "its lane change"
    else:
        raise InputError(f"a stop after {target.behaviour.value} is not a sequence LangTraj steers", where="target")
    stop = max(done + STOP_AFTER_M, v * v / (2 * COMFORT_DECELERATION) + 0.5)  # and half a metre to come to rest
    length = float(arc_lengths(target.path)[-1]) if len(target.path) >= 2 else 0.0
    if stop > length:
        reason = f"its way past {what} ends before a stop {stop:.0f} m ahead"
        raise TargetUnavailable(target.track_id, target.behaviour, "infeasible", reason)
    cruise = max(v, STOP_AFTER_MIN_SPEED)
    braking = min(cruise * cruise / (2 * COMFORT_DECELERATION), stop)  # the metres it brakes over
    standing = (stop - braking) / cruise + 2 * braking / cruise
    if standing > STOP_AFTER_BY_S:
        reason = f"a stop past {what} ({stop:.0f} m ahead) is beyond its reach in {STOP_AFTER_BY_S:g} s"
        raise TargetUnavailable(target.track_id, target.behaviour, "infeasible", reason)
    return replace(
        target,
        reason=f"{target.reason}, then a stop {stop:.0f} m ahead",
        station_of_goal=float(stop),
        speed=0.0,
        settled_s=float(standing),
    )
