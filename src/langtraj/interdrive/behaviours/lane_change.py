"""Changing lanes to the left or right: the neighbour lane on that side along the agent's road ahead, with room
before its next junction for the change to settle; judged by the labelers' lane-change label with its side.
See docs/interdrive.md ('Targets and feasibility')."""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from langtraj.interdrive.behaviour import Behaviour, BehaviourSpec, Side
from langtraj.interdrive.behaviours.base import BehaviourKind, Steer, register, route, steps
from langtraj.interdrive.behaviours.recipes import then_stop
from langtraj.interdrive.reader.words import OBJ, POSSESSIVE, verb
from langtraj.interdrive.targets.context import (
    LANE_CHANGE_MIN_M,
    LANE_CHANGE_S,
    AgentHere,
    TargetContext,
    into_lane,
)
from langtraj.interdrive.targets.target import BehaviourTarget, TargetUnavailable

# ---------------------------------------------------------------------------------------------- words

_MOTION = verb(
    "change", "switch", "swap", "move", "shift", "get", "pull", "merge", "nip", "hop", "slide", "cut", "go", "head",
    "drift", "slip", "slot", "jump", "steer", "ease", "edge", "pop", "duck", "tuck", "weave", "dart", "squeeze",
    "cross", "step", "glide", "drop", "come",
)  # fmt: skip
_SIDESTEP = verb(
    "move", "shift", "get", "merge", "nip", "hop", "slide", "cut", "drift", "slip", "slot", "jump", "steer", "ease",
    "edge", "pop", "duck", "tuck", "weave", "dart", "squeeze", "step", "glide",
)  # fmt: skip
"""Verbs of moving across to a side without naming a lane ("moves over to the left"); not "pulls over to the
right", which is pulling over."""
_POSITIONS = (
    r"(?:left|leftmost|left-most|far-left|far\s+left|left-hand)",
    r"(?:middle|center|centre|central)",
    r"(?:right|rightmost|right-most|far-right|far\s+right|right-hand)",
)
"""Lane position words by order from left to right."""


def _lane_np(side: str) -> str:
    """A lane on `side`: "the left lane", "the lane on its left", "the neighbouring lane to the left"."""
    words = r"(?:(?!(?:and|then|but|or)\b)[\w'-]+\s+){0,2}?"
    side_word = rf"(?:{side}|{side}-hand|far-{side}|far\s+{side}|{side}most|{side}-most)"
    det = r"(?:(?:the|a|an|its|your|their|one)\s+)?"
    return (
        rf"(?:{det}{words}{side_word}\s+lanes?\b"
        rf"|{det}{words}lanes?\s+{words}(?:on|to|at)\s+{POSSESSIVE}\s+(?:far\s+)?{side}\b(?!-hand\s+side|\s+side))"
    )


def _lane_change_words(side: str) -> list[str]:
    to_side = rf"(?:to(?:wards)?\s+{POSSESSIVE}\s+(?:far\s+)?{side}|{side}wards?|{side})\b"
    not_place = r"(?![ -]?(?:hand\s+)?(?:side|kerb|curb|shoulder|verge|edge)\b)"
    return [
        rf"\b{_MOTION}{OBJ}(?:\s+(?:over|across|back|out))?\s+(?:into|to|onto|towards?|in\s+to|across|over)\s+{_lane_np(side)}",
        rf"\b{verb('get')}{OBJ}\s+in\s+{_lane_np(side)}",
        rf"\b{_MOTION}{OBJ}(?:\s+(?:over|across|back))?\s+(?:(?:one|a|1)\s+lane|lanes?)\s+(?:over\s+)?{to_side}{not_place}",
        rf"\b{_MOTION}{OBJ}\s+(?:over\s+)?(?:{side}|{side}wards?)\s+(?:one|a|1)\s+lane\b",
        rf"\b{side}(?:-hand)?[ -]lane[ -]change\b|\blane[ -]change\s+(?:to(?:wards)?|on)\s+{POSSESSIVE}\s+{side}\b",
        rf"\b{_SIDESTEP}{OBJ}\s+(?:over|across)\s+{to_side}{not_place}",
    ]


def _lane_from_to(side: str) -> list[str]:
    """Lane changes named by their lanes: "from the leftmost lane to the middle lane" is to the right."""
    out = []
    for i, src in enumerate(_POSITIONS):
        for j, dst in enumerate(_POSITIONS):
            if i != j and (j > i) == (side == "right"):
                out.append(
                    rf"\b{_MOTION}{OBJ}(?:\s+lanes?)?(?:\s+over)?\s+from\s+(?:the\s+)?{src}(?:\s+lane)?\s+"
                    rf"(?:to|into|over\s+to|across\s+to)\s+(?:the\s+)?{dst}(?:\s+lane)?\b"
                )
    return out


# ---------------------------------------------------------------------------------------------- target


def _lane_change(ctx: TargetContext, agent: AgentHere, behaviour: Behaviour, side: Side) -> BehaviourTarget:
    """The neighbour lane on `side` (`MapIndex.neighbour_lane`, the labelers' definition) at the first station of
    the agent's road ahead from where a change can begin (1 s or 4 m ahead), where that lane runs on without a
    junction long enough for a change begun there to settle in it (`LANE_CHANGE_S` at the agent's speed, at least
    `LANE_CHANGE_MIN_M`: the labelers count no change into a junction lane)."""
    index = ctx.index
    ctx.need_lane(agent, behaviour, "neighbour lanes")
    if index.neighbor_source == "none":
        raise TargetUnavailable(agent.track_id, behaviour, "undecided", "the map has no lane neighbour information")
    begin = max(4.0, 1.0 * agent.here.speed)
    room_needed = max(LANE_CHANGE_MIN_M, LANE_CHANGE_S * agent.here.speed)
    ahead = ctx.stations(agent)
    if not ahead:
        reason = "it is inside a junction, where lanes have no neighbours"
        raise TargetUnavailable(agent.track_id, behaviour, "undecided", reason)
    cramped = False
    for point in ahead:
        if point.distance < begin:
            continue
        found = index.neighbour_lane(point.lane, point.station, side)
        if found is None or index.is_junction[found[0]]:
            continue
        lane, station = found
        room = index.distance_to_junction(lane, station) if index.has_connectivity else math.inf
        if round(point.distance + room - begin, 2) < round(room_needed, 2):  # to the centimetre
            cramped = True  # the lane beside it runs into a junction before a change could settle in it
            continue
        path = into_lane(index, agent, lane, station)
        return BehaviourTarget(
            agent.track_id,
            behaviour,
            path,
            f"the lane on its {side}, from {point.distance:.0f} m ahead",
            current_speed=agent.here.speed,
            side=side,
            joins_m=float(np.linalg.norm(index.point_at(lane, station) - agent.xy)),
        )
    reason = f"no lane on its {side} along its road (within {agent.search:.0f} m)"
    if cramped:
        reason = f"the lane on its {side} runs into a junction before a change could settle in it"
    raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)


def _steer(target: BehaviourTarget) -> list[Steer]:
    """In the neighbour lane from 4 s on (the change itself is the model's: 2 to 4 s is typical); with a stop asked
    after it, at rest at its stop past the change (`recipes.then_stop`)."""
    terms = route(first=steps(4.0))
    return terms + then_stop(target) if target.stop else terms


class _LaneChange(BehaviourKind):
    side: Side
    then = ("stop",)

    def target(
        self, ctx: TargetContext, agent: AgentHere, other: AgentHere | None, asked: Mapping[str, float]
    ) -> BehaviourTarget:
        return _lane_change(ctx, agent, Behaviour(self.name), self.side)

    def steer(self, target: BehaviourTarget, other_driven: bool) -> list[Steer]:
        return _steer(target)


@register
class LaneChangeLeft(_LaneChange):
    """Changing into the lane on the left."""

    name = "lane_change_left"
    side = "left"
    spec = BehaviourSpec(
        Behaviour.LANE_CHANGE_LEFT, "@{agent} changes lanes to the left", "change lanes to the left",
        "changing_lanes", "left",
    )  # fmt: skip
    words = (*_lane_change_words("left"), *_lane_from_to("left"))
    subsumes = ()
    word_rank = 2


@register
class LaneChangeRight(_LaneChange):
    """Changing into the lane on the right."""

    name = "lane_change_right"
    side = "right"
    spec = BehaviourSpec(
        Behaviour.LANE_CHANGE_RIGHT, "@{agent} changes lanes to the right", "change lanes to the right",
        "changing_lanes", "right",
    )  # fmt: skip
    words = (*_lane_change_words("right"), *_lane_from_to("right"))
    word_rank = 4
