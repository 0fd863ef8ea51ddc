"""Going first: past the conflict point of the agent's way and the other's before the other gets there (it must be
able to get there first), judged by the detector's passing side of a yield. See docs/interdrive.md ('Targets and
feasibility')."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from langtraj.interdrive.behaviour import Behaviour, BehaviourSpec
from langtraj.interdrive.behaviours.base import (
    REACH_WEIGHT,
    ROUTE_WEIGHT,
    BehaviourKind,
    Steer,
    avoid,
    register,
    route,
    speed,
    station,
    steps,
)
from langtraj.interdrive.detector import passing_runs
from langtraj.interdrive.reader.words import OTHER, POSSESSIVE, gap, verb
from langtraj.interdrive.targets.context import AgentHere, TargetContext, order_target
from langtraj.interdrive.targets.target import BehaviourTarget
from langtraj.interdrive.taxonomy import InteractionType
from langtraj.scenario.model import FUTURE_STEPS

# ---------------------------------------------------------------------------------------------- words

_GO_FIRST_VERBS = verb(
    "go", "get", "pass", "cross", "proceed", "head", "enter", "clear", "claim", "make it", "squeeze", "nip", "slip",
    "shoot", "dart", "race", "rush", "jump", "turn", "merge", "pull out", "take", "set off", "drive", "move", "travel",
    "reach", "arrive", "cut",
)  # fmt: skip
_AHEAD_VERBS = verb(
    "go", "get", "pass", "cross", "proceed", "enter", "clear", "claim", "make it", "squeeze", "nip", "slip", "shoot",
    "dart", "race", "rush", "jump", "turn", "merge", "pull out", "cut", "reach",
)  # fmt: skip
"""Verbs of going ahead of another agent in time (not "drives ahead of @7", which says where it is)."""
_GO_FIRST = [
    rf"\b{_GO_FIRST_VERBS}{gap(5)}\s+(?:before|sooner\s+than|earlier\s+than)\s+{OTHER}",
    rf"\b{_AHEAD_VERBS}"
    rf"{gap(5)}\s+ahead\s+of\s+{OTHER}",
    rf"\b{verb('cross', 'dart', 'shoot', 'pass', 'go', 'turn')}"
    rf"(?:\s+(?:out|across))?\s+in\s+front\s+of\s+{OTHER}",
    rf"\b{verb('take', 'have', 'claim', 'keep', 'assert', 'use', 'exercise', 'get', 'seize')}"
    rf"\s+(?:{POSSESSIVE}\s+)?(?:right\s+of\s+way|right-of-way|priority|precedence)"
    rf"(?:\s+(?:over|from|ahead\s+of|before|against)\s+{OTHER})?",
    rf"\b(?:{_GO_FIRST_VERBS}|be|is|are){gap(3)}\s+first\b"
    r"(?!\s+(?:junction|intersection|left|right|exit|turn|turning|lane|road|street|time|one|lights)\b)",
    r"\bfirst\s+to\s+(?:go|cross|pass|enter|move|proceed|get\s+through|clear|drive)\b",
    rf"\b{verb('beat', 'outrun')}\s+{OTHER}",
    r"\b(?:do(?:es)?\s+not|do(?:es)?n't|never|won't|will\s+not|without|not)\s+(?:\w+\s+)?"
    rf"{verb('yield', 'give way', 'wait', 'stop', 'slow', 'slow down', 'brake', 'hold back')}\s+(?:to|for)\s+{OTHER}",
    rf"\b(?:while|whilst|as|with)\s+{OTHER}\s+"
    rf"{verb('yield', 'give way', 'wait', 'hold back')}(?:\s+(?:to|for)\s+(?:it|them|him|her))?\b",
    rf"\b{verb('have', 'take', 'get')}\s+(?:its|your|their|his|her|the)\s+turn\s+(?:before|ahead\s+of)\s+{OTHER}",
]


def go_first_terms(target: BehaviourTarget, route_weight: float = 0.25 * ROUTE_WEIGHT) -> list[Steer]:
    """Past the conflict point (by 5 m) a second before the other agent gets there, clear of it; with no conflict
    point, at least its speed (3 m/s or more); on its way at `route_weight`."""
    t = target
    if t.station_of_goal is None or t.other_eta is None:  # keep going, clear of the other agent
        return speed(max(t.current_speed, 3.0), 1) + route(weight=route_weight) + avoid(1.0)
    by = int(np.clip(steps(t.other_eta - 1.0), 10, FUTURE_STEPS))
    return (
        station(t.station_of_goal + 5.0, "reach", by, FUTURE_STEPS, REACH_WEIGHT)
        + route(weight=route_weight)
        + avoid(1.0)
    )


@register
class GoFirst(BehaviourKind):
    """Taking the right of way over another agent."""

    name = "go_first"
    spec = BehaviourSpec(
        Behaviour.GO_FIRST, "@{agent} takes the right of way over @{other}", "go first",
        interaction=InteractionType.PASSING, subtype="passing/intersection_with_yielding", first=True,
    )  # fmt: skip
    words = tuple(_GO_FIRST)
    word_rank = 17
    subsumes = ("speed_up",)
    pair_runs = staticmethod(passing_runs)

    def target(
        self, ctx: TargetContext, agent: AgentHere, other: AgentHere | None, asked: Mapping[str, float]
    ) -> BehaviourTarget:
        assert other is not None
        return order_target(ctx, agent, other, Behaviour.GO_FIRST)

    def steer(self, target: BehaviourTarget, other_driven: bool) -> list[Steer]:
        return go_first_terms(target)
