"""Yielding: held before the conflict point of the agent's way and the other's until the other has passed (always
possible: it can wait), judged by the detector's yield rule. See docs/interdrive.md ('Targets and feasibility')."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from langtraj.interdrive.behaviour import Behaviour, BehaviourSpec
from langtraj.interdrive.behaviours.base import (
    HOLD_WEIGHT,
    BehaviourKind,
    Steer,
    avoid,
    register,
    speed,
    station,
    steps,
)
from langtraj.interdrive.detector import yielding_runs
from langtraj.interdrive.reader.words import OTHER, POSSESSIVE, TIGHT_GAP, gap, verb
from langtraj.interdrive.targets.context import AgentHere, TargetContext, order_target
from langtraj.interdrive.targets.target import BehaviourTarget
from langtraj.interdrive.taxonomy import InteractionType
from langtraj.scenario.model import FUTURE_STEPS

# ---------------------------------------------------------------------------------------------- words

_YIELD = [
    rf"\b{verb('yield', 'give way', 'defer', 'cede', 'submit')}"
    rf"(?:\s+(?:the\s+)?(?:right\s+of\s+way|right-of-way|priority|precedence|the\s+junction))?\s+(?:to|for)\s+{OTHER}",
    rf"\b{verb('give up', 'hand over', 'surrender', 'concede')}\s+(?:the\s+|its\s+)?(?:right\s+of\s+way|right-of-way"
    rf"|priority|precedence)\s+to\s+{OTHER}",
    rf"\b{verb('give', 'grant', 'leave', 'offer')}\s+{OTHER}\s+(?:the\s+|its\s+)?(?:right\s+of\s+way|right-of-way"
    r"|priority|precedence|way|room|space|the\s+go-ahead|a\s+chance|the\s+gap)\b",
    rf"\b{verb('let', 'allow', 'permit', 'wave', 'invite')}\s+{OTHER}\s+(?:to\s+)?"
    r"(?:through|by|past|in|ahead|out|on|over|first|[a-z]+)\b"
    r"(?:\s+(?:first|by|past|through|ahead(?!\s+of)|across|in\s+front|over|on|in|(?:the|its)\s+(?:right\s+of\s+way|turn)"
    r"|priority))*",
    rf"\b(?:{verb('wait', 'stop', 'slow', 'brake', 'hold', 'pause', 'halt', 'hang', 'stay', 'sit', 'hover')}"
    rf"(?:\s+(?:down|back|off|up|hard|\w+ly))?|{verb('make', 'leave')}\s+(?:room|way|space|a\s+gap))"
    rf"{gap(4)}\s+(?:for|until|till)\s+{OTHER}",
    rf"\b{verb('hang', 'hold', 'stay', 'keep', 'sit', 'wait', 'hover', 'drop')}\s+back\b(?:{TIGHT_GAP}{OTHER})?",
    rf"\b(?:so|so\s+that|allowing|letting|to\s+let|and\s+let)\s+{OTHER}\s+(?:can\s+|could\s+|may\s+|is\s+able\s+to\s+)?"
    r"(?:go|pass|cross|proceed|get\s+(?:by|past|through|in)|merge|enter|clear|through|by|past)\w*"
    r"(?:\s+(?:first|by|past|through|ahead(?!\s+of)|across|in))*",
    rf"\b{verb('wait')}\s+(?:{POSSESSIVE})\s+turn\b(?:\s+(?:behind|after)\s+{OTHER})?",
    rf"\bafter\s+{OTHER}\s+(?:has\s+|have\s+)?(?:passed|gone|crossed|cleared|gone\s+by|gone\s+through|got\s+through)\b",
    rf"\b{verb('yield', 'give way')}\b",
]


@register
class Yield(BehaviourKind):
    """Yielding to another agent."""

    name = "yield"
    spec = BehaviourSpec(
        Behaviour.YIELD, "@{agent} yields to @{other}", "yield", interaction=InteractionType.YIELDING,
        subtype="yielding/intersection",
    )  # fmt: skip
    words = tuple(_YIELD)
    word_rank = 18
    subsumes = ("stop", "slow_down")
    pair_runs = staticmethod(yielding_runs)

    def target(
        self, ctx: TargetContext, agent: AgentHere, other: AgentHere | None, asked: Mapping[str, float]
    ) -> BehaviourTarget:
        assert other is not None
        return order_target(ctx, agent, other, Behaviour.YIELD)

    def steer(self, target: BehaviourTarget, other_driven: bool) -> list[Steer]:
        """Held before the conflict point until two seconds after the other agent gets there, slow meanwhile, and
        clear of it; with no conflict point, at 30 % of its speed for 4 s."""
        t = target
        if t.station_of_goal is None or t.other_eta is None:  # slow in the first half, clear of the other agent
            return speed(0.3 * t.current_speed, 1, steps(4.0)) + avoid(3.0)
        until = int(np.clip(steps(t.other_eta + 2.0), 20, FUTURE_STEPS))
        hold = max(t.station_of_goal - 4.0, 0.0)
        return station(hold, "hold", 1, until, HOLD_WEIGHT) + speed(0.0, steps(1.0), until) + avoid(3.0)
