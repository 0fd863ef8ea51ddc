"""Turning left or right, or going straight, at the next junction: the lanes of the junction's branch in that
direction, from the agent to past its exit, judged by the labelers' turn and crossing labels.
See docs/interdrive.md ('Targets and feasibility')."""

from __future__ import annotations

from collections.abc import Mapping

from langtraj.interdrive.behaviour import AT_JUNCTION, BEHAVIOURS, Behaviour, BehaviourSpec
from langtraj.interdrive.behaviours.base import REACH_WEIGHT, BehaviourKind, Steer, register, route, station, steps
from langtraj.interdrive.behaviours.recipes import then_stop
from langtraj.interdrive.reader.words import POSSESSIVE, verb
from langtraj.interdrive.targets.context import AgentHere, TargetContext
from langtraj.interdrive.targets.lanes_ahead import branch_direction
from langtraj.interdrive.targets.target import BehaviourTarget, TargetUnavailable
from langtraj.roads.routes import route as lane_route
from langtraj.scenario.model import FUTURE_STEPS

# ---------------------------------------------------------------------------------------------- words

_NOT_LANE = r"(?![ -]?(?:hand\s+)?(?:lanes?|side|kerb|curb|shoulder|verge|edge|of\s+way|-of-way)\b)"
"""Not "the left lane", "the right side", "the right of way": a side word that names no turn."""
_NOT_ADVERB = r"(?!\s+(?:ahead|away|now|there|here|behind|where|after|before|back|up|through|past|across|on)\b)"
"""Not "go right ahead", "turn right away"."""
_TURN_VERBS = verb("turn", "swing", "steer", "bear", "head", "go", "hook", "hang", "branch", "fork", "peel", "wheel")
_TURN_TAKE = verb("hang", "take", "make", "hook", "do", "pull", "throw", "swing", "bang", "hit", "execute", "perform")
_TURN_DET = (
    r"(?:a|an|the)"
    r"(?:\s+(?:next|first|second|third|upcoming|coming|following|sharp|quick|hard|tight|wide|gentle|slight))*"
)
_TURN_NOUN = r"(?:road|street|turning|turn|exit|branch|arm|fork|avenue|way)"
_JUNCTION = r"(?:junction|intersection|crossroads|roundabout|lights|crossing)"


def _turn_words(side: str) -> list[str]:
    s = rf"(?:{side}(?:-hand)?|{side}wards?)"
    exit_verbs = verb("exit", "leave", "turn out of", "come out of")
    return [
        rf"\b{_TURN_VERBS}(?:\s+(?:off|away|round|around|out|sharply|hard))?"
        rf"(?:\s+to(?:wards)?\s+{POSSESSIVE}\s+|\s+){s}\b{_NOT_LANE}{_NOT_ADVERB}",
        rf"\b{_TURN_TAKE}\s+{_TURN_DET}\s+{side}(?:-hand)?(?:[ -](?:turn|turning|hander))?\b{_NOT_LANE}",
        rf"\b{side}(?:-hand)?[ -]turn(?:ing)?\b(?![ -]lanes?\b)",
        rf"\b{_TURN_NOUN}\s+(?:on|to)\s+{POSSESSIVE}\s+{side}\b{_NOT_LANE}",
        rf"\b(?:onto|into|down|up|along|via)\s+{_TURN_DET}\s+{side}(?:-hand)?\s+{_TURN_NOUN}\b",
        rf"\b{exit_verbs}(?:\s+(?:the|a)\s+{_JUNCTION})?\s+(?:(?:to(?:wards)?|on|by|via)\s+{POSSESSIVE}\s+)?{s}\b"
        rf"{_NOT_LANE}{_NOT_ADVERB}",
        rf"\b{verb('make')}\s+{POSSESSIVE}\s+way\s+(?:to(?:wards)?\s+the\s+|over\s+to\s+the\s+)?{s}\b{_NOT_LANE}",
    ]


_GO_ON = verb(
    "go", "keep", "continue", "carry", "head", "proceed", "drive", "travel", "move", "ride", "cycle", "walk", "stay",
    "run", "push", "press", "cruise", "roll",
)  # fmt: skip
_STRAIGHT = [
    rf"\b{_GO_ON}(?:\s+(?:on|going|driving|right|dead|directly))?\s+straight\b(?!\s*(?:away|after|afterwards|off|back)\b)",
    r"\bstraight\s+(?:on|ahead|through|over|across)\b",
    r"\b(?:without\s+(?:turning|making\s+(?:a|any)\s+turns?)|no\s+turns?|no\s+turning|making\s+no\s+turns?)\b"
    r"(?!\s+(?:left|right|off\s+to))",
    r"\bin\s+a\s+straight\s+line\b|\bstraight\s+course\b",
    r"\bin\s+the\s+same\s+direction\b(?!\s+as\b)",
    rf"\b{verb('stay', 'keep', 'remain')}\s+on\s+(?:this|the\s+same|its|your|their|the\s+current|the\s+main)"
    r"\s+(?:road|street|route)\b",
]

# ---------------------------------------------------------------------------------------------- target


def _turn(ctx: TargetContext, agent: AgentHere, behaviour: Behaviour) -> BehaviourTarget:
    """The nearest branch of the next junction in the asked direction: the lanes to it, the junction lanes, and past
    the exit; the goal station lies 5 m past the junction."""
    index = ctx.index
    ctx.need_lane(agent, behaviour, "junction directions")
    if not index.has_connectivity:
        reason = "the map has no lane connectivity to follow its lane to a junction"
        raise TargetUnavailable(agent.track_id, behaviour, "undecided", reason)
    reach = agent.search
    found = ctx.junction(agent)
    if not found.branches:
        if found.ends:
            reason = f"its lanes end within {reach:.0f} m with no junction (the map stops there)"
            raise TargetUnavailable(agent.track_id, behaviour, "undecided", reason)
        if behaviour is Behaviour.GO_STRAIGHT:
            reason = f"no junction within {reach:.0f} m: going straight is its road"
            raise TargetUnavailable(agent.track_id, behaviour, "undecided", reason)
        raise TargetUnavailable(
            agent.track_id, behaviour, "infeasible", f"no junction within {reach:.0f} m along its lanes"
        )
    directions = {b: branch_direction(b.turn, ctx.config) for b in found.branches}
    mine = [b for b in found.branches if directions[b] is behaviour]
    if not mine:
        words = {
            Behaviour.TURN_LEFT: "left turn",
            Behaviour.GO_STRAIGHT: "straight on",
            Behaviour.TURN_RIGHT: "right turn",
        }
        allowed = ", ".join(w for b, w in words.items() if b in directions.values()) or "only U-turns or bends"
        reason = f"no {words[behaviour]} from its lane at the next junction (it allows: {allowed})"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    branch = min(mine, key=lambda b: b.exit_at)
    goal = branch.exit_at + 5.0
    path = lane_route(index, branch.lanes, agent.here.station, max(agent.reach, goal + 25.0))
    return BehaviourTarget(
        agent.track_id,
        behaviour,
        path,
        f"the {BEHAVIOURS[behaviour].manoeuvre} branch of the next junction, its exit {branch.exit_at:.0f} m ahead",
        station_of_goal=goal,
        current_speed=agent.here.speed,
    )


def _steer(target: BehaviourTarget) -> list[Steer]:
    """On the branch's lanes throughout; past the junction's exit by 7.5 s, or, with a stop asked after it
    (`interdrive.targets.stop_after`), at rest at its stop past the exit (`recipes.then_stop`)."""
    terms = route()
    if target.stop:
        return terms + then_stop(target)
    if target.station_of_goal is not None:
        terms += station(target.station_of_goal, "reach", steps(7.5), FUTURE_STEPS, REACH_WEIGHT)
    return terms


class _Turn(BehaviourKind):
    then = ("stop",)

    def target(
        self, ctx: TargetContext, agent: AgentHere, other: AgentHere | None, asked: Mapping[str, float]
    ) -> BehaviourTarget:
        return _turn(ctx, agent, Behaviour(self.name))

    def steer(self, target: BehaviourTarget, other_driven: bool) -> list[Steer]:
        return _steer(target)


@register
class TurnLeft(_Turn):
    """Turning left at the next junction."""

    name = "turn_left"
    spec = BehaviourSpec(
        Behaviour.TURN_LEFT, "@{agent} turns left at the next intersection", "turn left", "turning_left",
        also=AT_JUNCTION,
    )  # fmt: skip
    words = tuple(_turn_words("left"))
    word_rank = 1


@register
class TurnRight(_Turn):
    """Turning right at the next junction."""

    name = "turn_right"
    spec = BehaviourSpec(
        Behaviour.TURN_RIGHT, "@{agent} turns right at the next intersection", "turn right", "turning_right",
        also=AT_JUNCTION,
    )  # fmt: skip
    words = tuple(_turn_words("right"))
    word_rank = 3


@register
class GoStraight(_Turn):
    """Going straight through the next junction."""

    name = "go_straight"
    spec = BehaviourSpec(
        Behaviour.GO_STRAIGHT, "@{agent} goes straight through the next intersection", "go straight",
        "going_straight", also=AT_JUNCTION,
    )  # fmt: skip
    words = tuple(_STRAIGHT)
    word_rank = 6
