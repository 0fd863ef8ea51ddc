"""Cutting in front of another agent (Euro NCAP's cut-in): into the other's lane, beside the agent's, settled the asked
gap ahead of it; judged by the detector's cut-in rule and by its numbers (the gap when it settles: `judge`).
See docs/interdrive.md ('Targets and feasibility') and docs/testing.md ('Judged by numbers')."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import replace

from langtraj.interdrive.behaviour import Behaviour, BehaviourSpec
from langtraj.interdrive.behaviours.base import BehaviourKind, Parameter, Steer, register, route, steps
from langtraj.interdrive.behaviours.recipes import gap_ahead
from langtraj.interdrive.behaviours.scripts import CuttingIn, Script
from langtraj.interdrive.detector import cut_in_runs
from langtraj.interdrive.judging import cut_in as judged_by
from langtraj.interdrive.reader.words import OTHER, verb
from langtraj.interdrive.targets.context import (
    GO_FIRST_ACCELERATION,
    LANE_CHANGE_S,
    AgentHere,
    TargetContext,
    into_lane,
    keeps_going,
    lane_beside,
    lead_of,
    offset_of,
)
from langtraj.interdrive.targets.target import BehaviourTarget, TargetUnavailable
from langtraj.interdrive.taxonomy import InteractionType
from langtraj.roads.routes import route as lane_route
from langtraj.scenario.types import AgentType

CUT_IN_GAP_M = 10.0
"""The gap (bumper to bumper, m) a cut-in leaves in front of the other agent unless the prompt gives one."""
CUT_IN_S = 1.0 + LANE_CHANGE_S
"""When a cut-in has settled in the other's lane (s): begun within 1 s, settled `LANE_CHANGE_S` later."""
GAP = Parameter(
    "gap", "m", CUT_IN_GAP_M, 2.0, 30.0, "metres",
    "bumper to bumper ahead of the other once settled: nearer is a collision, farther no cut-in",
)  # fmt: skip
"""The gap a cut-in (or an overtake and cut-in) is asked with ("with a 15 m gap")."""

# ---------------------------------------------------------------------------------------------- words

CUT_IN_VERBS = verb(
    "cut", "nip", "dive", "swerve", "squeeze", "slot", "tuck", "merge", "slip", "jump", "weave", "change lanes",
    "switch lanes", "move over", "pull in", "pull over", "barge", "force its way", "push in",
)  # fmt: skip
CUT_MANNER = r"(?:over|back|across|sharply|suddenly|right|just|closely|dangerously|abruptly|tightly|aggressively)"
JUST_AHEAD = r"(?:in\s+front\s+of|ahead\s+of|just\s+ahead\s+of)"
CUTS_IN = rf"{CUT_IN_VERBS}(?:\s+(?:in|{CUT_MANNER}))*\s+(?:{JUST_AHEAD}|in\s+on)"
"""A cut in front of someone named next: "cuts in front of", "swerves sharply in ahead of", "cuts in on"."""
_CUT_IN = [
    rf"\b{CUTS_IN}\s+{OTHER}",
    rf"\b{verb('cut', 'push', 'barge')}\s+in\s+on\s+{OTHER}",
    rf"\b{verb('cut')}\s+(?:off|up)\s+{OTHER}",
    rf"\b{verb('cut')}\s+{OTHER}\s+(?:off|up)\b",
    rf"\b{verb('change lanes', 'switch lanes', 'move', 'merge', 'cut', 'pull', 'swerve', 'squeeze')}"
    rf"(?:\s+(?:over|across))?\s+(?:in)?to\s+{OTHER}'s\s+lane\b"
    r"(?:\s+(?:right\s+|just\s+)?(?:in\s+front\s+of|ahead\s+of)\s+(?:it|them|him|her))?",
]
"""Changing into the other's lane just ahead of it (Euro NCAP's cut-in); "pulls out in front of @7" is a pull-out
(from a side road, not a lane beside it: `_PULL_OUT`)."""

# ---------------------------------------------------------------------------------------------- target


def out_of_path(agent: AgentHere, other: AgentHere, behaviour: Behaviour) -> None:
    """Infeasible where the agent's centre is already within the judge's `OUT_OF_PATH_M` of the other's heading line:
    it follows or leads the other (a lane merging into the other's), and no settling in its path could count as a
    cut-in (`judging.cut_in.out_of_path_step`)."""
    across = offset_of(agent, other)
    if abs(across) < judged_by.OUT_OF_PATH_M:
        reason = f"it is {abs(across):.1f} m to the side of @{other.track_id}: already in its path, not beside it"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)


def _cut_in(ctx: TargetContext, agent: AgentHere, other: AgentHere, gap: float) -> BehaviourTarget:
    """Into the other's lane when it lies beside the agent's (`_lane_beside`) at the agent or at a station of its
    road ahead, from where a change can begin (1 s or 4 m ahead); the `speed` is the average that puts the agent's
    rear `gap` m ahead of the other's front at `CUT_IN_S`, the other keeping its speed, and `station_of_goal` where
    along the path that average takes it by then.
    Infeasible where the agent is in the other's path already (`out_of_path`), where that needs more than
    `GO_FIRST_ACCELERATION` could add, or less than standing still, or where
    someone stands in the other's lane before the place the cut-in settles (`TargetContext.standing_on`: the other
    stops behind it first), the car ahead of the other leaves no room for the gap and the agent (`room_ahead`), a red
    light or a walker on the other's way stops it before the cut-in has settled (`keeps_going`), or a car ahead in
    its own lane leaves it no room to get there (`CUT_IN_ROOM_M`)."""
    behaviour = Behaviour.CUT_IN
    out_of_path(agent, other, behaviour)
    begin = max(4.0, 1.0 * agent.here.speed)
    side, lane, level = lane_beside(ctx, agent, other, behaviour, begin + 20.0)
    v, v_other = agent.here.speed, other.here.speed
    lengths = 0.5 * (agent.length + other.length)
    lead = lead_of(agent, other)
    speed = (v_other * CUT_IN_S + gap + lengths - lead) / CUT_IN_S
    most = v + 0.5 * GO_FIRST_ACCELERATION * CUT_IN_S
    if speed > most:
        reason = f"it cannot get {gap:g} m ahead of @{other.track_id} in {CUT_IN_S:g} s ({speed:.1f} m/s on average)"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    if speed < 0.0:
        reason = f"it is {lead:.0f} m ahead of @{other.track_id}: too far to cut in {gap:g} m ahead of it"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    own = ctx.ahead(agent)
    goal = float(speed * CUT_IN_S)
    ahead = ctx.first_on(agent, own, goal + agent.length + 30.0)
    if ahead is not None and ahead[0] != other.track_id:
        room = ahead[1] + ahead[2] * CUT_IN_S - goal - 0.5 * agent.length - CUT_IN_ROOM_M
        if room < 0.5 * agent.length:  # its centre short of where the cut-in must take it
            reason = f"@{ahead[0]} ahead of it in its lane leaves no room to get {gap:g} m ahead of @{other.track_id}"
            raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    settles = v_other * CUT_IN_S + gap + lengths + other.length
    if (queued := ctx.standing_on(other, ctx.ahead(other), settles)) is not None:
        reason = f"@{queued} stands in @{other.track_id}'s lane within the {settles:.0f} m the cut-in needs ahead of it"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    keeps_going(ctx, agent, other, behaviour, CUT_IN_S + judged_by.SETTLED_HOLD_S)
    room_ahead(ctx, agent, other, behaviour, gap, CUT_IN_S)
    return BehaviourTarget(
        agent.track_id,
        behaviour,
        into_lane(ctx.index, agent, lane, level + begin),
        f"@{other.track_id}'s lane on its {side}, {gap:g} m ahead of it, at {speed:.1f} m/s",
        station_of_goal=float(speed * CUT_IN_S),
        speed=float(speed),
        other_id=other.track_id,
        current_speed=v,
        other_speed=v_other,
        side=side,
        settled_s=CUT_IN_S,
        lead_m=float(gap + lengths),
        own_lane=ctx.ahead(agent),
        new_lane=lane_route(ctx.index, [lane], level, agent.reach + begin),
    )


def room_ahead(
    ctx: TargetContext, agent: AgentHere, other: AgentHere, behaviour: Behaviour, gap: float, seconds: float
) -> None:
    """Infeasible where the vehicle ahead of the other in its lane (`TargetContext.first_on`), at its speed, leaves less
    than the agent's length, `gap` and `CUT_IN_ROOM_M` between them `seconds` on (the other keeping its speed): the
    place the cut-in would settle in is taken (on validation scenes `suggest` offered 10-m cut-ins in front of an ego
    whose lead was 5 m ahead of it in a queue; none moved across)."""
    reach = other.here.speed * seconds + gap + agent.length + other.length + CUT_IN_ROOM_M
    ahead = ctx.first_on(other, ctx.ahead(other), reach, kind=AgentType.VEHICLE)
    if ahead is None:
        return
    track, apart, speed = ahead
    room = apart + (speed - other.here.speed) * seconds - 0.5 * (other.length + ctx.length(track))
    if room < gap + agent.length + CUT_IN_ROOM_M:
        reason = (
            f"@{track} ahead of @{other.track_id} in its lane leaves {max(room, 0.0):.0f} m, no room for "
            f"a {gap:g} m gap and the car"
        )
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)


CUT_IN_ROOM_M = 2.0
"""The least bumper gap (m) a cut-in keeps to the car ahead of it in its own lane where it must get to (at its goal,
that car at its speed): with less it cannot get ahead of the other without running into it."""
CUT_IN_READY_MIN_SPEED = 3.0
"""The least speed (m/s) of the agent cut in on for a staged cut-in to start: in front of a car standing in a queue
there is nothing to cut in on."""


CUT_IN_SLOWER = 6.0
"""How much slower than the other agent drove at the start (m/s) a scripted cut-in drives on once settled: a slower
vehicle cutting in (Euro NCAP's cut-in tests a slower target), closing a 10-m gap on a follower that keeps its speed
in under 2 s, within a scenario's 8 s (3 m/s left it 3 s, past the end)."""


def cruise(target: BehaviourTarget) -> float:
    """The speed a scripted cut-in drives on at once settled (`CUT_IN_SLOWER`)."""
    return max(float(target.other_speed or target.current_speed) - CUT_IN_SLOWER, 0.0)


def ready(target: BehaviourTarget) -> str | None:
    """Why a cut-in (or an overtake and cut-in) should wait: the other standing (`CUT_IN_READY_MIN_SPEED`), or None.
    Otherwise it starts at once: its script keeps its own lane and lets the other come up (or catches up with it)
    until it can move across at about its gap (`scripts.CuttingIn`); waiting unprompted instead, the agent drove
    away from the other or out of the lane beside it, and 0 of 20 validation cut-ins happened under the IDM."""
    other_speed = float(target.other_speed or 0.0)
    if other_speed < CUT_IN_READY_MIN_SPEED:
        return f"@{target.other_id} drives at {other_speed:.1f} m/s (a cut-in needs {CUT_IN_READY_MIN_SPEED:g} or more)"
    return None


CUT_IN_NATURAL_SLOWER = 2.0
"""How much slower (m/s, on average over `CUT_IN_S`) than it drives a cut-in `suggest` offers may ask its agent to go:
more, and it would have to drop back for the other to come up first (on validation scenes, offered cutters 50-75 m
ahead of the ego that had to slow by 14 m/s never came to cut in)."""


def natural(target: BehaviourTarget) -> str | None:
    """Why `suggest` does not offer a cut-in (or an overtake and cut-in): its agent would have to slow by more than
    `CUT_IN_NATURAL_SLOWER` for the other to come up; else None."""
    if target.speed is not None and target.speed < target.current_speed - CUT_IN_NATURAL_SLOWER:
        return (
            f"it would slow from {target.current_speed:.1f} to {target.speed:.1f} m/s for @{target.other_id} to come up"
        )
    return None


CHANGE_AND_SPEED = ("lane_change_left", "lane_change_right", "speed_up", "slow_down")
"""What a cut-in's words also say, as part of it: a lane change, speeding up or slowing down."""


@register
class CutIn(BehaviourKind):
    """Cutting in front of another agent."""

    name = "cut_in"
    spec = BehaviourSpec(
        Behaviour.CUT_IN, "@{agent} cuts in front of @{other}", "cut in front of",
        interaction=InteractionType.LANE_CHANGE, subtype="lane_change/cut_in", exact=True,
        conditioned_as=Behaviour.LANE_CHANGE_LEFT,
    )  # fmt: skip
    words = tuple(_CUT_IN)
    word_rank = 12
    subsumes = CHANGE_AND_SPEED
    in_path = True
    parameters = (GAP,)
    judged = staticmethod(judged_by.judge)
    pair_runs = staticmethod(cut_in_runs)

    def target(
        self, ctx: TargetContext, agent: AgentHere, other: AgentHere | None, asked: Mapping[str, float]
    ) -> BehaviourTarget:
        assert other is not None
        return _cut_in(ctx, agent, other, asked["gap"])

    def ready(self, target: BehaviourTarget) -> str | None:
        return ready(target)

    def natural(self, target: BehaviourTarget) -> str | None:
        return natural(target)

    def script(self, target: BehaviourTarget) -> Script | None:
        """Into the other's lane ahead of it, settling the asked gap wherever the other drives, then on at
        `CUT_IN_SLOWER` below the other's speed at the start (`CuttingIn`); guidance alone left most cut-ins
        unsettled or turned across the lane (docs/testing.md, 'Scenarios staged on the ego's live state')."""
        if target.lead_m is None:
            return None
        moves = 0.0 if target.starts_s is None else float(target.starts_s)
        return CuttingIn(float(target.lead_m), float(target.settled_s or CUT_IN_S), cruise(target), moves)

    def placed(self, target: BehaviourTarget, within_m: float | None = None) -> BehaviourTarget | None:
        """Its lead beside the other in its own lane at the other's speed, never moving across (`CuttingIn`'s
        `moves_from_s`; its path its own lane): when the trigger holds, the cut-in is where it can begin at once. None
        for a trigger on the gap between the two (`within_m`), which its lead would not bring about."""
        if within_m is not None or target.lead_m is None or target.own_lane is None or len(target.own_lane) < 2:
            return None
        reason = f"keeps its lead beside @{target.other_id} in its own lane until it starts"
        return replace(target, path=target.own_lane, starts_s=math.inf, reason=reason)

    def steer(self, target: BehaviourTarget, other_driven: bool) -> list[Steer]:
        """The gap ahead of the other agent when the change has settled (`CUT_IN_S`) and after
        (`recipes.gap_ahead`); in the other's lane from 2 s on."""
        return gap_ahead(target, other_driven) + route(first=steps(2.0))
