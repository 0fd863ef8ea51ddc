"""Braking hard in front of another agent (Euro NCAP's braking lead vehicle, CCRb): in its lane ahead of the other,
braking at the asked deceleration to rest; judged by the detector's braking-lead rule and by its numbers (the peak
deceleration, staying in the follower's path: `judge`). See docs/interdrive.md ('Targets and feasibility')."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import replace

import numpy as np

from langtraj.interdrive.behaviour import Behaviour, BehaviourSpec
from langtraj.interdrive.behaviours.base import (
    HOLD_WEIGHT,
    ROUTE_WEIGHT,
    BehaviourKind,
    Parameter,
    Steer,
    register,
    route,
    speed,
    station,
    steps,
)
from langtraj.interdrive.behaviours.recipes import settled
from langtraj.interdrive.behaviours.scripts import Braking, Script
from langtraj.interdrive.detector import braking_lead_runs
from langtraj.interdrive.judging import brake_hard as judged_by
from langtraj.interdrive.judging.base import IN_PATH_LATERAL_M
from langtraj.interdrive.reader.words import IN_FRONT, OTHER, TIGHT_GAP, verb
from langtraj.interdrive.targets.context import AgentHere, TargetContext, pair_gap
from langtraj.interdrive.targets.target import BehaviourTarget, TargetUnavailable
from langtraj.interdrive.taxonomy import InteractionType
from langtraj.polylines import point_at, project_on_polyline
from langtraj.scenario.model import FUTURE_STEPS

BRAKE_HARD_DECELERATION = 4.0
"""How hard a braking lead brakes unless the prompt says (m/s^2): Euro NCAP's braking-lead tests use 2 to 6."""
BRAKE_HARD_LIMITS = (3.0, 10.0)
"""The decelerations a braking lead may be asked for (m/s^2): at least the judge's hard braking
(`DetectorConfig.hard_braking`), at most what tyres give on dry asphalt (about 1 g)."""
BRAKE_HARD_AFTER_S = 1.0
"""When a braking lead starts braking (s): the follower has a second of the scene as it was."""
BRAKE_HARD_MIN_SPEED = 4.0
"""The least speed a braking lead must have (m/s): slower, hard braking lasts too short to judge."""
BRAKE_HARD_EASE_OFF_SPARE_MPS = 2.0
"""How much faster than it must be to brake hard (`brake_hard_min_speed`) a braking lead easing off for its
follower stays (m/s; `BrakeHard.placed`)."""
BRAKE_HARD_READY_S = 3.0
"""The time headway (s) its follower must be within for a braking lead staged on the follower's live state to start
braking (`BrakeHard.ready`)."""
DECELERATION = Parameter(
    "deceleration", "m/s^2", BRAKE_HARD_DECELERATION, *BRAKE_HARD_LIMITS, "deceleration",
    "hard braking, and at most what tyres give on dry asphalt",
)  # fmt: skip
"""How hard a braking lead is asked to brake ("at 6 m/s^2", "at 0.5 g")."""
WAY_STEP_M = 1.0
"""How finely a braking lead's way to its rest is checked against its follower's (m; `_on_their_way`)."""
QUEUE_GAP_M = 2.0
"""The least bumper gap (m) the vehicle ahead of a braking lead, driving on at its speed, leaves past the lead's rest
point: less, and the lead is queued behind it (`_not_queued`), the standing gap of the agents' IDM."""
QUEUE_REACH_M = 30.0
"""How far past its rest point a braking lead looks for the vehicle ahead (m)."""
KEEP_LANE_WEIGHT = 16.0 * ROUTE_WEIGHT
"""Per m^2 off the lane, for a braking lead, which must not swerve: above the common range, as the model, conditioned
on a stop, moves aside by 1.5-3 m at 1x; chosen on validation maps (docs/testing.md, 'The safety-critical
vocabulary')."""

# ---------------------------------------------------------------------------------------------- words

_HARD = r"(?:hard|sharply|suddenly|abruptly|heavily|violently|harshly|fiercely|firmly|urgently|all\s+of\s+a\s+sudden)"
_DECELERATION_WORDS = r"(?:\s+(?:at|with|by)\s+(?:a\s+deceleration\s+of\s+)?[\d.]+\s*(?:m/s\^?2|m/s²|m/s/s|g)(?!\w))"
"""A deceleration the text gives ("at 6 m/s^2", "at 0.5 g"), read by `read.py`'s `_DECELERATION`."""
_BRAKE_HARD = [
    rf"\b{verb('brake', 'stop', 'decelerate')}(?:(?:\s+{_HARD})+(?:\s+and\s+{_HARD})?{_DECELERATION_WORDS}?"
    rf"|{_DECELERATION_WORDS})\s+{IN_FRONT}\s+{OTHER}",
    rf"\b{verb('slam on', 'stamp on', 'jam on', 'stand on', 'mash', 'hit', 'smash')}\s+(?:the|its|their|his|her)"
    rf"\s+brakes?{TIGHT_GAP}\s+{IN_FRONT}\s+{OTHER}",
    rf"\b{verb('do', 'make', 'perform', 'carry out', 'execute')}\s+an?\s+(?:emergency|hard|sudden|panic|abrupt)"
    rf"\s+(?:stop|brake|braking\s+manoeuvre|braking\s+maneuver|braking){TIGHT_GAP}\s+{IN_FRONT}\s+{OTHER}",
    rf"\b{verb('brake-check', 'brake check', 'brake test', 'brake-test')}\s+{OTHER}",
    rf"\b{verb('force', 'make', 'cause')}\s+{OTHER}\s+to\s+(?:brake|slow\s+down|stop|slam\s+on\s+the\s+brakes)\b"
    rf"(?:\s+{_HARD})?",
]
"""Braking hard in the other's lane just ahead of it (Euro NCAP's braking lead vehicle): "brakes hard in front of
@7", "slams on the brakes ahead of @7", "brake-checks @7", "forces @7 to brake"."""

# ---------------------------------------------------------------------------------------------- target


def brake_hard_min_speed(deceleration: float) -> float:
    """The least speed (m/s) a lead braking at `deceleration` must have: `BRAKE_HARD_MIN_SPEED`, and enough not to
    stop within the judge's 0.5-s window (`deceleration` over `judging.brake_hard.PEAK_WINDOW_S`), which would read
    less: it binds beyond 8 m/s^2."""
    return max(BRAKE_HARD_MIN_SPEED, deceleration * judged_by.PEAK_WINDOW_S)


def _brake_hard(ctx: TargetContext, agent: AgentHere, other: AgentHere, deceleration: float) -> BehaviourTarget:
    """The agent's lane ahead and the stop that braking at `deceleration` from `BRAKE_HARD_AFTER_S` brings it to,
    the other following within `FOLLOWER_RANGE_M` (Euro NCAP's braking lead vehicle). Infeasible for a deceleration
    outside `BRAKE_HARD_LIMITS`, an agent slower than `brake_hard_min_speed`, or no such follower."""
    behaviour, v = Behaviour.BRAKE_HARD, agent.here.speed
    low, high = BRAKE_HARD_LIMITS
    if not low <= deceleration <= high:
        reason = f"braking at {deceleration:g} m/s^2 is outside {low:g} to {high:g} m/s^2 (hard, and what tyres give)"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    if v < (least := brake_hard_min_speed(deceleration)):
        reason = f"it is too slow to brake hard at {deceleration:g} m/s^2 ({v:.1f} m/s; at least {least:g})"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    gap = pair_gap(ctx, agent, other, behaviour, lead=agent, where="behind")
    way = ctx.ahead(other)  # read once: a staged braking lead derives its target at every step it waits
    _nearest_lead(ctx, agent, other, way, gap)
    station = v * BRAKE_HARD_AFTER_S + v * v / (2.0 * deceleration)
    path = ctx.ahead(agent)
    _on_their_way(agent, other, path, way, station)
    _not_queued(ctx, agent, path, station, BRAKE_HARD_AFTER_S + v / deceleration)
    return BehaviourTarget(
        agent.track_id,
        behaviour,
        path,
        f"braking at {deceleration:g} m/s^2 from {BRAKE_HARD_AFTER_S:g} s to rest {station:.0f} m ahead, "
        f"@{other.track_id} {gap:.0f} m behind",
        station_of_goal=float(station),
        speed=0.0,
        other_id=other.track_id,
        current_speed=v,
        other_speed=other.here.speed,
        settled_s=BRAKE_HARD_AFTER_S + v / deceleration,
        deceleration=float(deceleration),
        other_gap_m=float(gap),
    )


def _nearest_lead(ctx: TargetContext, agent: AgentHere, other: AgentHere, way: np.ndarray, gap: float) -> None:
    """Infeasible where another road user is on the other's `way` between it and the agent (`TargetContext.first_on`
    within the `gap`): the other follows that one, and the agent's braking is in front of it, not of the other."""
    found = ctx.first_on(other, way, gap + 0.5 * other.length)
    if found is None or found[0] == agent.track_id:
        return
    reason = f"@{found[0]} is between @{other.track_id} and it"
    raise TargetUnavailable(agent.track_id, Behaviour.BRAKE_HARD, "infeasible", reason)


def _on_their_way(agent: AgentHere, other: AgentHere, path: np.ndarray, way: np.ndarray, upto: float) -> None:
    """Infeasible where the agent's `path` parts from the other's `way` (`TargetContext.ahead`: its route, where it
    drives one) by more than the judge's `IN_PATH_LATERAL_M` before the agent comes to rest `upto` m along it: a
    follower that turns off at the junction ahead is braked in front of by no one (the judge reads the lead in the
    follower's driven path)."""
    if len(path) < 2 or len(way) < 2:
        return
    stations = np.arange(0.0, upto + 0.5 * agent.length, WAY_STEP_M)
    off = project_on_polyline(point_at(path, stations), way).distance
    if (off <= IN_PATH_LATERAL_M).all():
        return
    parts = float(stations[int(np.argmax(off > IN_PATH_LATERAL_M))])
    reason = f"its lane parts from @{other.track_id}'s way {parts:.0f} m ahead, before it would come to rest"
    raise TargetUnavailable(agent.track_id, Behaviour.BRAKE_HARD, "infeasible", reason)


def _not_queued(ctx: TargetContext, agent: AgentHere, path: np.ndarray, upto: float, rest_s: float) -> None:
    """Infeasible where the vehicle ahead of the agent on its `path`, driving on at its speed, is less than
    `QUEUE_GAP_M` past where the agent comes to rest (`upto` m along it, `rest_s` s from now): the agent is stopping
    behind it anyway, slowing already (a queue), and what it does is no hard braking staged in front of anyone."""
    found = ctx.first_on(agent, path, upto + QUEUE_REACH_M)
    if found is None:
        return
    ahead, length, speed = found[1], ctx.length(found[0]), found[2]
    room = ahead + speed * rest_s - 0.5 * (agent.length + length) - upto
    if room >= QUEUE_GAP_M:
        return
    reason = (
        f"it is queued behind @{found[0]} {ahead - 0.5 * (agent.length + length):.0f} m ahead, stopping for it anyway"
    )
    raise TargetUnavailable(agent.track_id, Behaviour.BRAKE_HARD, "infeasible", reason)


@register
class BrakeHard(BehaviourKind):
    """Braking hard in front of another agent."""

    name = "brake_hard"
    spec = BehaviourSpec(
        Behaviour.BRAKE_HARD, "@{agent} brakes hard in front of @{other}", "brake hard in front of",
        interaction=InteractionType.PASSING, subtype="passing/braking_lead", exact=True,
        conditioned_as=Behaviour.STOP,
    )  # fmt: skip
    words = tuple(_BRAKE_HARD)
    word_rank = 13
    subsumes = ("stop", "slow_down")
    in_path = True
    parameters = (DECELERATION,)
    judged = staticmethod(judged_by.judge)
    pair_runs = staticmethod(braking_lead_runs)

    def target(
        self, ctx: TargetContext, agent: AgentHere, other: AgentHere | None, asked: Mapping[str, float]
    ) -> BehaviourTarget:
        assert other is not None
        return _brake_hard(ctx, agent, other, asked["deceleration"])

    def script(self, target: BehaviourTarget) -> Script | None:
        """Braking at the asked deceleration from `BRAKE_HARD_AFTER_S` to rest in its lane, executed exactly:
        guidance alone let the model, conditioned on a stop, brake at 5.5-13 m/s^2 when 4 was asked, and swerve
        (docs/testing.md, 'Scenarios staged on the ego's live state')."""
        start = BRAKE_HARD_AFTER_S if target.starts_s is None else target.starts_s
        deceleration = float(target.deceleration or BRAKE_HARD_DECELERATION)
        if target.closes_to_m is None:
            return Braking(start, deceleration)
        floor = brake_hard_min_speed(deceleration) + BRAKE_HARD_EASE_OFF_SPARE_MPS
        return Braking(start, deceleration, target.closes_to_m, floor)

    def placed(self, target: BehaviourTarget, within_m: float | None = None) -> BehaviourTarget | None:
        """For a trigger on its follower's gap ("when @ego is within 20 m of @4, @4 brakes hard"): in its lane,
        easing off until the follower is within it (`scripts.ease_off`), no slower than its braking needs, so that it
        brakes with the follower at the asked gap whatever the follower's planner does; a follower that hangs back
        behind a lead at that speed never brings it about, and the report says how far back it was."""
        if within_m is None or target.other_id is None:
            return None
        reason = f"eases off until @{target.other_id} is within {within_m:g} m"
        return replace(target, starts_s=math.inf, closes_to_m=float(within_m), reason=reason)

    def at_trigger(self, target: BehaviourTarget) -> BehaviourTarget:
        """Braking at once: the prompt's trigger says when ("when @ego is within 20 m of @738, ..."), not the second
        the follower otherwise has of the scene as it was (`BRAKE_HARD_AFTER_S`)."""
        return replace(target, starts_s=0.0)

    def ready(self, target: BehaviourTarget) -> str | None:
        """Not before its follower is within `BRAKE_HARD_READY_S` of time headway (Euro NCAP's braking lead brakes
        with its follower 12-40 m behind at 50 km/h: 0.9-2.9 s): braking with the follower far behind tests nothing.
        A prompt that says when (`at_trigger`: "when @ego is within 20 m of @4") is obeyed as it says."""
        if target.starts_s is not None:
            return None
        speed = max(float(target.other_speed or 0.0), 0.1)
        gap = float(target.other_gap_m or 0.0)
        if gap > BRAKE_HARD_READY_S * speed:
            return (
                f"@{target.other_id} is {gap:.0f} m behind at {speed:.1f} m/s ({gap / speed:.1f} s; it brakes within "
                f"{BRAKE_HARD_READY_S:g} s)"
            )
        return None

    def steer(self, target: BehaviourTarget, other_driven: bool) -> list[Steer]:
        """At its speed until braking starts, never past the stop point, standing still from when braking at the
        asked deceleration gets there (`settled_s`); in its lane throughout (a braking lead does not swerve)."""
        return (
            speed(target.current_speed, 1, steps(BRAKE_HARD_AFTER_S))
            + station(float(target.station_of_goal or 0.0), "hold", 1, FUTURE_STEPS, HOLD_WEIGHT)
            + speed(0.0, settled(target))
            + route(weight=KEEP_LANE_WEIGHT)
        )
