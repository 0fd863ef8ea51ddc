"""Tailgating another agent: closing to a short headway behind it in its lane and holding it; judged by the detector's
tailgating rule and by its numbers (the headway and for how long: `judge`). See docs/interdrive.md ('Targets and
feasibility')."""

from __future__ import annotations

from collections.abc import Mapping

from langtraj.interdrive.behaviour import Behaviour, BehaviourSpec
from langtraj.interdrive.behaviours.base import BehaviourKind, Steer, register, route
from langtraj.interdrive.behaviours.recipes import at_station_then_speed
from langtraj.interdrive.behaviours.scripts import Following, Script
from langtraj.interdrive.detector import tailgating_runs
from langtraj.interdrive.judging import tailgate as judged_by
from langtraj.interdrive.reader.words import OTHER, verb
from langtraj.interdrive.targets.context import JUDGE, AgentHere, TargetContext, keeps_going, pair_gap
from langtraj.interdrive.targets.target import BehaviourTarget, TargetUnavailable
from langtraj.interdrive.taxonomy import InteractionType
from langtraj.scenario.model import STEP_SECONDS

TAILGATE_HEADWAY_S = 0.4
"""The time gap a tailgater closes to (s): under the judge's 0.6 s (`DetectorConfig.tailgating_headway_s`)."""
TAILGATE_MIN_SPEED = 6.0
"""The least speed of the agent tailgated (m/s): the judge's tailgating needs 5 m/s."""
TAILGATE_CLOSING = 3.0
"""How much faster than the other a tailgater closes the gap (m/s on average), within `TAILGATE_WITHIN_S`."""
TAILGATE_WITHIN_S = 6.0
"""The latest a tailgater must have closed to its short headway (s): later, the judge may not see it tailgate."""

# ---------------------------------------------------------------------------------------------- words

_TAILGATE = [
    rf"\b{verb('tailgate')}\s+{OTHER}",
    rf"\b{verb('follow', 'drive', 'stay', 'sit', 'keep', 'travel', 'ride', 'tail')}"
    rf"\s+(?:far\s+|way\s+|much\s+)?(?:too|dangerously|aggressively|uncomfortably|very|really|extremely)\s+"
    rf"close(?:ly)?\s+(?:behind|to|on|after)\s+{OTHER}",
    rf"\b{verb('follow', 'tail')}\s+{OTHER}\s+(?:far\s+|way\s+|much\s+)?(?:too|dangerously|aggressively"
    r"|uncomfortably|very|really|extremely)\s+close(?:ly)?\b",
    rf"\b{verb('ride', 'sit on', 'hug', 'crowd')}\s+{OTHER}'s\s+(?:bumper|tail|rear)\b",
    rf"\b{verb('ride', 'sit on', 'hug', 'crowd')}\s+the\s+(?:bumper|tail|rear)\s+of\s+{OTHER}",
    rf"\b{verb('sit', 'stay', 'drive', 'be')}\s+(?:right\s+)?on\s+{OTHER}'s\s+(?:bumper|tail)\b",
]
"""Following the other too closely (the detector's tailgating: under 0.6 s of headway at speed)."""

# ---------------------------------------------------------------------------------------------- target


def _tailgate(ctx: TargetContext, agent: AgentHere, other: AgentHere) -> BehaviourTarget:
    """The agent's lane ahead and the station where its gap to the other, keeping its speed, is `TAILGATE_HEADWAY_S`
    of headway, closed `TAILGATE_CLOSING` m/s faster than the other (at least 2 s), then the other's speed.
    Infeasible where the other is not ahead in its lane within `FOLLOWER_RANGE_M`, is slower than
    `TAILGATE_MIN_SPEED`, the gap cannot be closed within `TAILGATE_WITHIN_S`, or a red light or a walker on its way
    stops the other before the judge's second of tailgating after that (`keeps_going`: a stop ends any tailgating)."""
    behaviour, v_other = Behaviour.TAILGATE, other.here.speed
    gap = pair_gap(ctx, agent, other, behaviour, lead=other, where="ahead of")
    if v_other < TAILGATE_MIN_SPEED:
        reason = f"@{other.track_id} is too slow to tailgate ({v_other:.1f} m/s; at least {TAILGATE_MIN_SPEED:g})"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    want = TAILGATE_HEADWAY_S * v_other
    within = max(2.0, (gap - want) / TAILGATE_CLOSING)
    if within > TAILGATE_WITHIN_S:
        reason = f"@{other.track_id} is {gap:.0f} m ahead: too far to close to {want:.0f} m in {TAILGATE_WITHIN_S:g} s"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    keeps_going(ctx, agent, other, behaviour, within + JUDGE.min_follow_steps * STEP_SECONDS)
    return BehaviourTarget(
        agent.track_id,
        behaviour,
        ctx.ahead(agent),
        f"{want:.0f} m behind @{other.track_id} ({TAILGATE_HEADWAY_S:g} s at {v_other:.1f} m/s) within {within:.1f} s",
        station_of_goal=float(v_other * within + gap - want),
        speed=float(v_other),
        other_id=other.track_id,
        current_speed=agent.here.speed,
        other_speed=float(v_other),
        settled_s=float(within),
    )


@register
class Tailgate(BehaviourKind):
    """Tailgating another agent."""

    name = "tailgate"
    spec = BehaviourSpec(
        Behaviour.TAILGATE, "@{agent} tailgates @{other}", "tailgate", interaction=InteractionType.FOLLOWING,
        subtype="following/tailgating", exact=True,
    )  # fmt: skip
    words = tuple(_TAILGATE)
    word_rank = 14
    subsumes = ("follow", "speed_up", "slow_down")
    judged = staticmethod(judged_by.judge)
    pair_runs = staticmethod(tailgating_runs)

    def target(
        self, ctx: TargetContext, agent: AgentHere, other: AgentHere | None, asked: Mapping[str, float]
    ) -> BehaviourTarget:
        assert other is not None
        return _tailgate(ctx, agent, other)

    def script(self, target: BehaviourTarget) -> Script | None:
        """Closing in behind the other to `TAILGATE_HEADWAY_S` at the other's speed as it is and staying there, along
        the way the other drives (`Following`); guidance alone kept the model's 1.6-1.7 s of headway, and a fixed
        distance behind an other that slowed came to 1.3-2 s (docs/testing.md, 'Scenarios staged on the ego's live
        state')."""
        return Following(TAILGATE_HEADWAY_S)

    def steer(self, target: BehaviourTarget, other_driven: bool) -> list[Steer]:
        """At the station that closes the gap behind the other agent when the target says, not past it before; at
        the other's speed after; in its lane throughout."""
        return at_station_then_speed(target) + route()
