"""Guidance toward a prompted agent's target: the terms that steer it to do what its prompt asks.

The extended CTG++-style library: where `guidance.library` maps a label to generic costs around the agent's
current pose, this maps a behaviour's target derived from the map (`interdrive.targets`) to route, station,
speed and spacing costs. Targets are timed in simulated steps from the start (1 ... 80); a replan that has
already executed `elapsed` steps gets the terms for what is left, in its own plan steps.

Common range, as in the library: a clear violation (1 m off the route, 5 m short of a goal, 2 m/s of speed
error) costs about 1.

See docs/simulation.md ('Prompts that steer').
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property
from typing import Literal

import numpy as np

from langtraj.frames import Origin, points_to_frame
from langtraj.guidance.base import GuidanceTerm
from langtraj.guidance.costs import NoCollisionCost, TargetSpeedCost
from langtraj.guidance.library import AVOID_WEIGHT, SPEED_WEIGHT
from langtraj.guidance.route import LeadCost, RouteCost, RoutePath, StationCost
from langtraj.interdrive.behaviour import BEHAVIOURS, Behaviour
from langtraj.interdrive.targets import BRAKE_HARD_AFTER_S, LANE_CHANGE_S, BehaviourTarget
from langtraj.scenario.model import FUTURE_STEPS, STEP_SECONDS

ROUTE_WEIGHT = 1.0  # per m^2 off the route
REACH_WEIGHT = 1 / 5.0**2  # per m^2 short of a goal station
HOLD_WEIGHT = 1 / 2.0**2  # per m^2 past a stop or conflict point
KEEP_LANE_WEIGHT = 16.0 * ROUTE_WEIGHT
"""Per m^2 off the lane, for a braking lead, which must not swerve: above the common range, as the model, conditioned
on a stop, moves aside by 1.5-3 m at 1x; chosen on validation maps (docs/testing.md, 'The safety-critical
vocabulary')."""
RED_LIGHT_ROUTE_WEIGHT = 1.25 * ROUTE_WEIGHT
"""Per m^2 off its way, for a red-light runner: going first's quarter weight and the usual one on top, as measured
(docs/testing.md, 'Red lights run by name, measured')."""
PULL_OUT_REACH_WEIGHT = 16.0 * REACH_WEIGHT
"""Per m^2 short of the meeting point, for a pull-out: above the common range, as the model, trained where cars on a
side road wait for the main road, holds it at the mouth; chosen on validation maps (docs/testing.md, 'Pulling out by
name, measured')."""
LEAD_SLACK_M = 2.0
"""How far beyond its settled lead an overtaking agent may get ahead of the other before it has settled (m)."""
CLEAR_WEIGHT = AVOID_WEIGHT  # per unit of summed disk overlap with the other agents (as the library keeps clear)
CLEAR_BUFFER = 0.5  # m kept beyond touching


class ClearOfOthersCost(NoCollisionCost):
    """`NoCollisionCost` of one agent against every other with the "sum" reduction (not divided by the square of
    the agents involved): the agent's total disk overlap, whatever the scene's size."""

    name = "clear_of_others"

    def __init__(self, slot: int, *, buffer: float = 0.0):
        super().__init__(slot, buffer=buffer, reduction="sum")


@dataclass(frozen=True)
class Steering:
    """A target in the scene frame with the model slots of its agent (and of the other agent, if simulated)."""

    target: BehaviourTarget
    slot: int
    other_slot: int | None = None

    @classmethod
    def of(cls, target: BehaviourTarget, origin: Origin, slots: dict[int, int]) -> Steering:
        """`target` (world frame) moved into the scene frame of `origin`; `slots` maps track ids to slots."""
        moved = replace(
            target,
            path=points_to_frame(target.path, origin) if len(target.path) else target.path,
            conflict=None if target.conflict is None else points_to_frame(target.conflict, origin),
        )
        other = None if target.other_id is None else slots.get(target.other_id)
        return cls(moved, slots[target.track_id], other)

    @cached_property
    def route(self) -> RoutePath:
        """The target's path as the route costs take it, built once for every replan's terms."""
        return RoutePath(self.target.path)

    def terms(self, elapsed: int, horizon: int) -> list[GuidanceTerm]:
        """The terms for a plan of `horizon` steps made after `elapsed` simulated steps: toward the target, and
        clear of every other agent (so that a step toward the target does not drive into someone)."""
        terms = _BUILDERS[self.target.behaviour](self, _Clock(elapsed, horizon))
        if not terms:
            return terms
        return [*terms, GuidanceTerm(ClearOfOthersCost(self.slot, buffer=CLEAR_BUFFER), CLEAR_WEIGHT)]


@dataclass(frozen=True)
class _Clock:
    """Simulated steps (1 = the first after the start) to plan steps of a replan after `elapsed` steps."""

    elapsed: int
    horizon: int

    def window(self, first: int = 1, last: int = FUTURE_STEPS) -> tuple[int, int] | None:
        """Plan steps [start, end) covering simulated steps first ... last; None when none is left."""
        start = max(first - self.elapsed - 1, 0)
        end = min(last - self.elapsed, self.horizon)
        return (start, end) if end > start else None


def _route(s: Steering, clock: _Clock, first: int = 1, last: int = FUTURE_STEPS, weight: float = ROUTE_WEIGHT) -> list:
    span = clock.window(first, last)
    if span is None or len(s.target.path) < 2:
        return []
    return [GuidanceTerm(RouteCost(s.slot, s.route, start=span[0], end=span[1]), weight)]


def _station(s: Steering, clock: _Clock, station: float, mode: str, first: int, last: int, weight: float) -> list:
    span = clock.window(first, last)
    if span is None or len(s.target.path) < 2:
        return []
    cost = StationCost(s.slot, s.route, station, mode=mode, start=span[0], end=span[1])  # type: ignore[arg-type]
    return [GuidanceTerm(cost, weight)]


def _speed(s: Steering, clock: _Clock, speed: float, first: int, last: int = FUTURE_STEPS) -> list:
    span = clock.window(first, last)
    if span is None:
        return []
    return [GuidanceTerm(TargetSpeedCost(s.slot, max(speed, 0.0), start=span[0], end=span[1]), SPEED_WEIGHT)]


def _avoid(s: Steering, buffer: float) -> list:
    if s.other_slot is None:
        return []
    return [GuidanceTerm(NoCollisionCost(s.slot, others=s.other_slot, buffer=buffer), AVOID_WEIGHT)]


def _steps(seconds: float) -> int:
    return round(seconds / STEP_SECONDS)


def _turn(s: Steering, clock: _Clock) -> list:
    """On the branch's lanes throughout; past the junction's exit by 7.5 s, or, with a stop asked after it
    (`interdrive.targets.stop_after`), at rest at its stop past the exit (`_then_stop`)."""
    goal = s.target.station_of_goal
    terms = _route(s, clock)
    if s.target.stop:
        return terms + _then_stop(s, clock)
    if goal is not None:
        terms += _station(s, clock, goal, "reach", _steps(7.5), FUTURE_STEPS, REACH_WEIGHT)
    return terms


def _lane_change(s: Steering, clock: _Clock) -> list:
    """In the neighbour lane from 4 s on (the change itself is the model's: 2 to 4 s is typical); with a stop asked
    after it, at rest at its stop past the change (`_then_stop`)."""
    terms = _route(s, clock, first=_steps(4.0))
    return terms + _then_stop(s, clock) if s.target.stop else terms


def _then_stop(s: Steering, clock: _Clock) -> list:
    """A stop after a manoeuvre (`interdrive.targets.stop_after`, which times it): standing still at its stop from
    when the target has it stand (`settled_s`: driving on, then braking comfortably)."""
    settled = s.target.settled_s
    if settled is None:
        raise ValueError(f"a stop after {s.target.behaviour.value} needs its time to stand (settled_s)")
    return _stand(s, clock, int(np.clip(_steps(settled), 10, FUTURE_STEPS - 10)))


def _stand(s: Steering, clock: _Clock, standing: int) -> list:
    """Never past the stop point; standing still from simulated step `standing` on."""
    goal = s.target.station_of_goal or 0.0
    return _station(s, clock, goal, "hold", 1, FUTURE_STEPS, HOLD_WEIGHT) + _speed(s, clock, 0.0, standing)


def _stop_step(s: Steering) -> int:
    """When braking evenly from the current speed to the goal station brings the agent to rest (at most 6 s)."""
    goal, v = s.target.station_of_goal or 0.0, max(s.target.current_speed, 0.1)
    return int(np.clip(_steps(2 * goal / v), 10, 60))


def _stop(s: Steering, clock: _Clock) -> list:
    """Never past the stop point; standing still from when even braking gets there."""
    return _stand(s, clock, _stop_step(s)) + _route(s, clock, weight=0.25 * ROUTE_WEIGHT)


def _pull_over(s: Steering, clock: _Clock) -> list:
    """On the kerb line from 2 s on, never past the stop point, standing still from when even braking gets
    there (at most 5.5 s, so the stop lasts the 2 s the labeler asks)."""
    return _route(s, clock, first=_steps(2.0)) + _stand(s, clock, min(_stop_step(s), _steps(5.5)))


def _speed_change(s: Steering, clock: _Clock) -> list:
    """The target speed from 3 s on, along its lane."""
    return _speed(s, clock, float(s.target.speed or 0.0), _steps(3.0)) + _route(s, clock, weight=0.25)


def _go_first(s: Steering, clock: _Clock, route_weight: float = 0.25 * ROUTE_WEIGHT) -> list:
    """Past the conflict point (by 5 m) a second before the other agent gets there, clear of it; with no conflict
    point, at least its speed (3 m/s or more); on its way at `route_weight`."""
    t = s.target
    if t.station_of_goal is None or t.other_eta is None:  # keep going, clear of the other agent
        return _speed(s, clock, max(t.current_speed, 3.0), 1) + _route(s, clock, weight=route_weight) + _avoid(s, 1.0)
    by = int(np.clip(_steps(t.other_eta - 1.0), 10, FUTURE_STEPS))
    goal = t.station_of_goal + 5.0
    return (
        _station(s, clock, goal, "reach", by, FUTURE_STEPS, REACH_WEIGHT)
        + _route(s, clock, weight=route_weight)
        + _avoid(s, 1.0)
    )


def _run_red_light(s: Steering, clock: _Clock) -> list:
    """As going first (past the crossing a second before the other agent gets there, clear of it), through the red
    light at its target speed from 1 s until then, on its way throughout: the model, which learned to stop at red
    lights, is held to it."""
    t = s.target
    by = int(np.clip(_steps((t.other_eta or 0.0) - 1.0), 10, FUTURE_STEPS))
    return _go_first(s, clock, RED_LIGHT_ROUTE_WEIGHT) + _speed(s, clock, float(t.speed or 0.0), _steps(1.0), by)


def _pull_out(s: Steering, clock: _Clock) -> list:
    """Where it stands until it sets off (`starts_s`), then out onto the other's way: past the meeting point (by
    5 m) when the target has it there (`settled_s`), on its way throughout, at its target speed a second later; and,
    where it joins the other's way, the target's lead ahead of where the other actually drives from then (`LeadCost`),
    so that a pull-out the other closes on is not given up."""
    t, settled = s.target, _settled(s.target)
    starts = _steps(t.starts_s or 0.0)
    goal = float(t.station_of_goal or 0.0) + 5.0
    terms = _route(s, clock) + _station(s, clock, goal, "reach", max(settled, 10), FUTURE_STEPS, PULL_OUT_REACH_WEIGHT)
    if starts > 0:
        terms += _station(s, clock, 0.5, "hold", 1, starts, HOLD_WEIGHT) + _speed(s, clock, 0.0, 1, starts)
    terms += _speed(s, clock, float(t.speed or 0.0), starts + _steps(1.0))
    if t.lead_m is not None:
        terms += _lead(s, clock, t.lead_m, "reach", settled, FUTURE_STEPS, REACH_WEIGHT)
    return terms


def _yield(s: Steering, clock: _Clock) -> list:
    """Held before the conflict point until two seconds after the other agent gets there, slow meanwhile, and
    clear of it; with no conflict point, at 30 % of its speed for 4 s."""
    t = s.target
    if t.station_of_goal is None or t.other_eta is None:  # slow in the first half, clear of the other agent
        return _speed(s, clock, 0.3 * t.current_speed, 1, _steps(4.0)) + _avoid(s, 3.0)
    until = int(np.clip(_steps(t.other_eta + 2.0), 20, FUTURE_STEPS))
    hold = max(t.station_of_goal - 4.0, 0.0)
    terms = _station(s, clock, hold, "hold", 1, until, HOLD_WEIGHT)
    return terms + _speed(s, clock, 0.0, _steps(1.0), until) + _avoid(s, 3.0)


def _follow(s: Steering, clock: _Clock) -> list:
    """Along the other agent's lane, at its speed, a gap behind it."""
    other_speed = s.target.other_speed if s.target.other_speed is not None else s.target.current_speed
    return _route(s, clock, weight=0.5) + _speed(s, clock, other_speed, 1) + _avoid(s, 2.0)


def _settled(target: BehaviourTarget) -> int:
    """The simulated step by which the target times its goal (`settled_s`), which a timed kind's target must give."""
    if target.settled_s is None:
        raise ValueError(f"a {target.behaviour.value} target must say when it is settled (settled_s)")
    return _steps(target.settled_s)


def _at_station_then_speed(s: Steering, clock: _Clock) -> list:
    """At the goal station when the target says (`settled_s`), not past it before; at the other agent's speed
    after."""
    t, settled = s.target, _settled(s.target)
    other_speed = t.other_speed if t.other_speed is not None else t.current_speed
    goal = float(t.station_of_goal or 0.0)
    return (
        _station(s, clock, goal, "reach", settled, settled + 5, REACH_WEIGHT)
        + _station(s, clock, goal, "hold", 1, settled, HOLD_WEIGHT)
        + _speed(s, clock, other_speed, settled)
    )


def _cut_in(s: Steering, clock: _Clock) -> list:
    """In the other's lane from 2 s on; the gap ahead of the other agent when the change has settled (`CUT_IN_S`)
    and after (`_gap_ahead`)."""
    return _gap_ahead(s, clock) + _route(s, clock, first=_steps(2.0))


def _gap_ahead(s: Steering, clock: _Clock) -> list:
    """The gap ahead of the other agent from when the target says it has settled, and never more than
    `LEAD_SLACK_M` beyond it before, measured against where the other agent drives in the plan (`LeadCost`), so that
    an agent cut in on that slows down is still cut in on. Where the model does not drive the other agent: at the
    goal station when settled, not past it before, at the other's speed after (`_at_station_then_speed`)."""
    t, settled = s.target, _settled(s.target)
    if s.other_slot is None or t.lead_m is None:
        return _at_station_then_speed(s, clock)
    return _lead(s, clock, t.lead_m, "reach", settled, FUTURE_STEPS, REACH_WEIGHT) + _lead(
        s, clock, t.lead_m + LEAD_SLACK_M, "hold", 1, FUTURE_STEPS, HOLD_WEIGHT
    )


def _overtake_cut_in(s: Steering, clock: _Clock) -> list:
    """At the passing speed from 1 s until the change begins (`LANE_CHANGE_S` before it settles), on its way
    throughout (its own lane past the other, then the other's), the gap ahead of the other once settled
    (`_gap_ahead`)."""
    t, settled = s.target, _settled(s.target)
    return (
        _speed(s, clock, float(t.speed or 0.0), _steps(1.0), settled - _steps(LANE_CHANGE_S))
        + _route(s, clock)
        + _gap_ahead(s, clock)
    )


def _lead(
    s: Steering, clock: _Clock, lead: float, mode: Literal["reach", "hold"], first: int, last: int, weight: float
) -> list:
    span = clock.window(first, last)
    if span is None or len(s.target.path) < 2 or s.other_slot is None:
        return []
    return [GuidanceTerm(LeadCost(s.slot, s.other_slot, s.route, lead, mode=mode, start=span[0], end=span[1]), weight)]


def _tailgate(s: Steering, clock: _Clock) -> list:
    """At the station that closes the gap behind the other agent when the target says, not past it before; at the
    other's speed after; in its lane throughout."""
    return _at_station_then_speed(s, clock) + _route(s, clock)


def _brake_hard(s: Steering, clock: _Clock) -> list:
    """At its speed until braking starts, never past the stop point, standing still from when braking at the asked
    deceleration gets there (`settled_s`); in its lane throughout (a braking lead does not swerve)."""
    t = s.target
    rest = _settled(t)
    start = _steps(BRAKE_HARD_AFTER_S)
    return (
        _speed(s, clock, t.current_speed, 1, start)
        + _station(s, clock, float(t.station_of_goal or 0.0), "hold", 1, FUTURE_STEPS, HOLD_WEIGHT)
        + _speed(s, clock, 0.0, rest)
        + _route(s, clock, weight=KEEP_LANE_WEIGHT)
    )


_BUILDERS = {
    Behaviour.TURN_LEFT: _turn,
    Behaviour.TURN_RIGHT: _turn,
    Behaviour.GO_STRAIGHT: _turn,
    Behaviour.LANE_CHANGE_LEFT: _lane_change,
    Behaviour.LANE_CHANGE_RIGHT: _lane_change,
    Behaviour.STOP: _stop,
    Behaviour.PULL_OVER: _pull_over,
    Behaviour.SPEED_UP: _speed_change,
    Behaviour.SLOW_DOWN: _speed_change,
    Behaviour.GO_FIRST: _go_first,
    Behaviour.YIELD: _yield,
    Behaviour.FOLLOW: _follow,
    Behaviour.CUT_IN: _cut_in,
    Behaviour.OVERTAKE_CUT_IN: _overtake_cut_in,
    Behaviour.BRAKE_HARD: _brake_hard,
    Behaviour.TAILGATE: _tailgate,
    Behaviour.RUN_RED_LIGHT: _run_red_light,
    Behaviour.PULL_OUT: _pull_out,
}
assert set(_BUILDERS) == set(BEHAVIOURS), "every behaviour kind needs a builder"
