"""Overtaking another agent and cutting in front of it (NHTSA's lane-change pre-crash scenarios): past it in the
agent's own lane, then into its lane, settled the asked gap ahead of it; judged by the detector's overtake-and-cut-in
rule and by its numbers. See docs/interdrive.md ('Targets and feasibility')."""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from langtraj.interdrive.behaviour import Behaviour, BehaviourSpec
from langtraj.interdrive.behaviours.base import BehaviourKind, Steer, register, route, speed, steps
from langtraj.interdrive.behaviours.cut_in import (
    CHANGE_AND_SPEED,
    CUT_IN_VERBS,
    CUT_MANNER,
    CUTS_IN,
    GAP,
    JUST_AHEAD,
    cruise,
    out_of_path,
    room_ahead,
)
from langtraj.interdrive.behaviours.cut_in import natural as cut_in_natural
from langtraj.interdrive.behaviours.cut_in import ready as cut_in_ready
from langtraj.interdrive.behaviours.recipes import gap_ahead, settled
from langtraj.interdrive.behaviours.scripts import CUT_IN_ACCELERATIONS, CuttingIn, Script
from langtraj.interdrive.detector import overtake_cut_in_runs
from langtraj.interdrive.judging import overtake_cut_in as judged_by
from langtraj.interdrive.judging.cut_in import SETTLED_HOLD_S
from langtraj.interdrive.reader.words import OTHER, verb
from langtraj.interdrive.targets.context import (
    FOLLOWER_RANGE_M,
    GO_FIRST_ACCELERATION,
    HORIZON_S,
    LANE_CHANGE_S,
    AgentHere,
    TargetContext,
    keeps_going,
    lane_beside,
    lead_of,
)
from langtraj.interdrive.targets.target import BehaviourTarget, TargetUnavailable
from langtraj.interdrive.taxonomy import InteractionType
from langtraj.polylines import resample
from langtraj.roads.routes import ROUTE_SPACING
from langtraj.roads.routes import route as lane_route
from langtraj.scenario.model import FUTURE_STEPS, STEP_SECONDS

OVERTAKE_GAIN = 4.0
"""How much faster than the other agent an overtake passes it (m/s), unless the agent is faster already."""
OVERTAKE_SHED_MPS = -CUT_IN_ACCELERATIONS[0] * LANE_CHANGE_S
"""The most an overtake's agent may be faster than the other (m/s) for `suggest` to offer it: what its script brakes
over a lane change (3.5 m/s^2 for 3 s), settling at the other's speed."""
OVERTAKE_LATEST_S = HORIZON_S - 1.0
"""By when an overtake must have settled in the other's lane (s): a second before the horizon, for the judge."""
OVERTAKE_MIN_SPEED = 5.0
"""The least speed of the agent overtaken (m/s): slower traffic is queued, not overtaken."""
OVERTAKE_CLEAR_M = 2.0
"""How far an overtaking agent's rear is past the other's front when its change into the other's lane begins (m),
unless the asked gap is smaller."""

# ---------------------------------------------------------------------------------------------- words

_PASS_VERBS = verb(
    "overtake", "pass", "get past", "go past", "get by", "go by", "get round", "go round", "get around", "go around",
    "race past", "speed past", "zoom past", "blow past", "shoot past", "drive past", "whizz past", "whiz past",
    "undertake", "outpace", "overhaul",
)  # fmt: skip
_FILLER_WORDS = r"(?:(?:sharply|suddenly|abruptly|quickly|immediately|right\s+away|aggressively)\s+)*"
_SAME = r"(?:it|them|him|her|(?P=other))"
"""The other agent named again after a pass ("overtakes @7 and cuts in front of it")."""
_THEN = r"(?:\s*,)?\s+(?:and\s+then|and|then|before|to)\s+"
_ITS_LANE = (
    rf"(?:back\s+)?(?:in)?to\s+(?:its|their|his|her|{_SAME}'s)\s+lane\b"
    rf"(?:\s+(?:right\s+|just\s+)?(?:in\s+front\s+of|ahead\s+of)\s+{_SAME})?"
)
_CUT_BACK = (
    rf"(?:{CUT_IN_VERBS}(?:\s+(?:in(?!\s+(?:front|on)\b)|{CUT_MANNER}))*(?:\s+(?:{JUST_AHEAD}|in\s+on)"
    rf"\s+{_SAME}|\s+{_ITS_LANE}|\s+(?:in|back)\b)?"
    rf"|{verb('move', 'pull', 'swing', 'swerve', 'get', 'go', 'steer', 'drift')}\s+{_ITS_LANE}"
    rf"|{verb('cut')}\s+(?:off\s+{_SAME}|{_SAME}\s+(?:off|up)))\b(?!\s+(?:in\s+)?(?:front|ahead|on|in)\b)"
)
"""The cut back in after a pass: "cuts in (front of it)", "pulls in ahead of it", "moves into its lane", "cuts it
off"."""
_OVERTAKE_CUT_IN = [
    rf"\b{_PASS_VERBS}\s+{OTHER}{_THEN}{_FILLER_WORDS}{_CUT_BACK}",
    rf"\b{_PASS_VERBS}(?:{_THEN}|\s+){_FILLER_WORDS}{CUTS_IN}\s+{OTHER}",
    rf"\b{CUTS_IN}\s+{OTHER}(?:\s*,)?\s+(?:(?:right|just)\s+)?(?:after|once)"
    rf"\s+{verb('overtake', 'pass', 'get past', 'go past')}\s+{_SAME}",
    rf"\b{_PASS_VERBS}\s+{OTHER}\s+and\s+{verb('cut')}\s+{_SAME}\s+(?:off|up)\b",
]
"""Passing the other and then changing into its lane just ahead of it: "overtakes @7 and cuts in front of it",
"passes @7, then pulls in ahead of it", "overtakes and cuts in front of @7", "cuts in front of @7 after passing it"
(NHTSA's lane-change pre-crash scenarios)."""

# ---------------------------------------------------------------------------------------------- target


def _overtake_cut_in(ctx: TargetContext, agent: AgentHere, other: AgentHere, gap: float) -> BehaviourTarget:
    """Past the other in the agent's own lane, then into the other's lane beside it (`_lane_beside`), settled `gap` m
    ahead of it, the other keeping its speed: the agent speeds up at `GO_FIRST_ACCELERATION` to `OVERTAKE_GAIN`
    faster than the other (or keeps its speed, if faster) until its rear is `OVERTAKE_CLEAR_M` past the other's front
    (not before 1 s), then changes lanes over `LANE_CHANGE_S`, gaining the rest of the gap on the way.
    `station_of_goal` is where it settles, `settled_s` when, `speed` the passing speed. Infeasible where the other is
    slower than `OVERTAKE_MIN_SPEED` (queued traffic is not overtaken), the agent is already ahead of it (a cut-in) or
    more than `FOLLOWER_RANGE_M` behind, it cannot settle by `OVERTAKE_LATEST_S`, the other's lane runs into a
    junction before it would, the car ahead of the other leaves no room for it (`room_ahead`), or a red light stops the
    other before it has settled (`keeps_going`)."""
    behaviour = Behaviour.OVERTAKE_CUT_IN
    out_of_path(agent, other, behaviour)
    side, lane, level = lane_beside(ctx, agent, other, behaviour, 10.0)
    v, v_other = agent.here.speed, other.here.speed
    if v_other < OVERTAKE_MIN_SPEED:
        reason = f"@{other.track_id} is too slow to overtake ({v_other:.1f} m/s; at least {OVERTAKE_MIN_SPEED:g})"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    lengths = 0.5 * (agent.length + other.length)
    lead = lead_of(agent, other)
    if lead - lengths > 0.0:
        reason = f"it is already ahead of @{other.track_id}: that is a cut-in, with no overtake"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    if -lead - lengths > FOLLOWER_RANGE_M:
        reason = f"it is {-lead - lengths:.0f} m behind @{other.track_id} (at most {FOLLOWER_RANGE_M:g})"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    need = gap + lengths - lead  # metres to gain on the other by the time it settles
    top = max(v, v_other + OVERTAKE_GAIN)
    t = np.arange(1, FUTURE_STEPS + 1) * STEP_SECONDS
    travelled = np.cumsum(np.minimum(v + GO_FIRST_ACCELERATION * t, top)) * STEP_SECONDS
    passed = (travelled - v_other * t >= lengths + min(OVERTAKE_CLEAR_M, gap) - lead) & (t >= 1.0 - 1e-9)
    k = int(np.argmax(passed))
    settle = float(t[k]) + LANE_CHANGE_S
    if not passed.any() or settle > OVERTAKE_LATEST_S + 1e-9:
        reason = (
            f"it cannot get {gap:g} m ahead of @{other.track_id} by {OVERTAKE_LATEST_S:g} s "
            f"({need:.0f} m to gain, passing at {top:.1f} m/s)"
        )
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    begin = float(travelled[k])
    goal = max(v_other * settle + need, begin)
    room = ctx.index.distance_to_junction(lane, level) if ctx.index.has_connectivity else math.inf
    if room < goal:
        reason = f"@{other.track_id}'s lane runs into a junction {room:.0f} m ahead, before it could settle there"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    keeps_going(ctx, agent, other, behaviour, settle + SETTLED_HOLD_S)
    room_ahead(ctx, agent, other, behaviour, gap, settle)
    path = _past_then_into_lane(ctx, agent, lane, level, begin, 0.5 * (goal - begin))
    if path is None:
        reason = f"@{other.track_id}'s lane ends before it could change into it"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    return BehaviourTarget(
        agent.track_id,
        behaviour,
        path,
        f"past @{other.track_id} at {top:.1f} m/s, then into its lane on its {side} from "
        f"{settle - LANE_CHANGE_S:.1f} s, {gap:g} m ahead of it by {settle:.1f} s",
        station_of_goal=float(goal),
        speed=float(top),
        other_id=other.track_id,
        current_speed=v,
        other_speed=v_other,
        side=side,
        own_lane=ctx.ahead(agent),
        new_lane=lane_route(ctx.index, [lane], level, goal + agent.reach),
        settled_s=settle,
        lead_m=float(gap + lengths),
    )


def _past_then_into_lane(
    ctx: TargetContext, agent: AgentHere, lane: int, level: float, begin: float, across: float
) -> np.ndarray | None:
    """The agent's own lane for `begin` m, then a straight line over `across` m into `lane` (whose station beside
    the agent is `level`), then that lane on: an overtake's way past and back in (None where `lane`, with what it
    leads into, ends before that)."""
    index = ctx.index
    own = lane_route(index, [agent.here.lane], agent.here.station, begin + ROUTE_SPACING)[
        : int(begin / ROUTE_SPACING) + 1
    ]
    theirs = lane_route(index, [lane], level, begin + across + agent.reach)[int((begin + across) / ROUTE_SPACING) :]
    if len(theirs) < 2:
        return None
    lead_in = resample(np.stack([own[-1], theirs[0]]), ROUTE_SPACING)
    return np.concatenate([own[:-1], lead_in[:-1], theirs])


@register
class OvertakeCutIn(BehaviourKind):
    """Overtaking another agent and cutting in front of it."""

    name = "overtake_cut_in"
    spec = BehaviourSpec(
        Behaviour.OVERTAKE_CUT_IN, "@{agent} overtakes @{other} and cuts in front of it",
        "overtake and cut in front of",
        interaction=InteractionType.OVERTAKING, subtype="overtaking/cut_in", exact=True,
        conditioned_as=Behaviour.LANE_CHANGE_LEFT,
    )  # fmt: skip
    words = tuple(_OVERTAKE_CUT_IN)
    word_rank = 11
    subsumes = ("cut_in", "go_first", *CHANGE_AND_SPEED)
    in_path = True
    parameters = (GAP,)
    judged = staticmethod(judged_by.judge)
    pair_runs = staticmethod(overtake_cut_in_runs)

    def target(
        self, ctx: TargetContext, agent: AgentHere, other: AgentHere | None, asked: Mapping[str, float]
    ) -> BehaviourTarget:
        assert other is not None
        return _overtake_cut_in(ctx, agent, other, asked["gap"])

    def ready(self, target: BehaviourTarget) -> str | None:
        """As a cut-in's (`cut_in.ready`): not in front of a car standing still."""
        return cut_in_ready(target)

    def natural(self, target: BehaviourTarget) -> str | None:
        """As a cut-in's (`cut_in.natural`), and not where its agent would have to shed more than its script brakes
        over a lane change (`OVERTAKE_SHED_MPS`) to settle at the other's speed: that is a pass, not a cut-in (a
        held-out overtaker at 29 m/s past an ego at 7 was 55 m ahead of it at the end, 10 asked)."""
        if target.other_speed is not None:
            shed = target.current_speed - target.other_speed
            if shed > OVERTAKE_SHED_MPS:
                return (
                    f"it would slow from {target.current_speed:.1f} to {target.other_speed:.1f} m/s to settle in "
                    f"front of @{target.other_id}: a pass, not a cut-in"
                )
        return cut_in_natural(target)

    def script(self, target: BehaviourTarget) -> Script | None:
        """Past the other and into its lane ahead of it, settling the asked gap wherever the other drives, then on
        slower than it (a cut-in's script, `CuttingIn`: straight on until clear ahead of it)."""
        if target.lead_m is None:
            return None
        return CuttingIn(float(target.lead_m), float(target.settled_s or 0.0), cruise(target))

    def steer(self, target: BehaviourTarget, other_driven: bool) -> list[Steer]:
        """At the passing speed from 1 s until the change begins (`LANE_CHANGE_S` before it settles), on its way
        throughout (its own lane past the other, then the other's), the gap ahead of the other once settled
        (`recipes.gap_ahead`)."""
        when = settled(target)
        return (
            speed(float(target.speed or 0.0), steps(1.0), when - steps(LANE_CHANGE_S))
            + route()
            + gap_ahead(target, other_driven)
        )
