"""Following: behind the other agent along its lane at its speed, judged by the detector's following rule.
See docs/interdrive.md ('Targets and feasibility')."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from langtraj.interdrive.behaviour import Behaviour, BehaviourSpec
from langtraj.interdrive.behaviours.base import BehaviourKind, Steer, avoid, register, route, speed
from langtraj.interdrive.detector import following_runs
from langtraj.interdrive.reader.words import OTHER, verb
from langtraj.interdrive.targets.context import AgentHere, TargetContext
from langtraj.interdrive.targets.target import BehaviourTarget
from langtraj.interdrive.taxonomy import InteractionType

# ---------------------------------------------------------------------------------------------- words

_BEHIND_VERBS = verb(
    "stay", "keep", "remain", "drive", "travel", "sit", "tuck", "fall", "slot", "hang", "queue", "ride", "drop",
    "settle", "line", "tag", "creep", "cruise", "trundle",
)  # fmt: skip
_FOLLOW = [
    rf"\b{verb('follow', 'trail', 'tail', 'shadow')}\s+(?:(?:close(?:ly)?\s+)?(?:behind|after)\s+)?{OTHER}",
    rf"\b{_BEHIND_VERBS}"
    rf"(?:\s+(?:in|back|up|right|directly|close|closely|just|along))*\s+behind\s+{OTHER}",
    rf"\b{verb('keep', 'maintain', 'hold')}\s+(?:a\s+)?(?:safe\s+|steady\s+|constant\s+|good\s+)?(?:distance|gap)"
    rf"\s+(?:behind|to)\s+{OTHER}",
    rf"\b(?:in\s+the\s+(?:wake|tracks|footsteps)\s+of|on\s+the\s+tail\s+of)\s+{OTHER}",
]


@register
class Follow(BehaviourKind):
    """Following another agent."""

    name = "follow"
    spec = BehaviourSpec(
        Behaviour.FOLLOW, "@{agent} follows @{other}", "follow", interaction=InteractionType.FOLLOWING,
        subtype="following/with_lead",
    )  # fmt: skip
    words = tuple(_FOLLOW)
    word_rank = 19
    subsumes = ("slow_down", "speed_up")
    pair_runs = staticmethod(following_runs)

    def target(
        self, ctx: TargetContext, agent: AgentHere, other: AgentHere | None, asked: Mapping[str, float]
    ) -> BehaviourTarget:
        assert other is not None
        path = ctx.ahead(other) if other.on_lane else np.zeros((0, 2))
        return BehaviourTarget(
            agent.track_id, Behaviour.FOLLOW, path, f"behind @{other.track_id} along its lane",
            other_id=other.track_id, current_speed=agent.here.speed, other_speed=other.here.speed,
        )  # fmt: skip

    def steer(self, target: BehaviourTarget, other_driven: bool) -> list[Steer]:
        """Along the other agent's lane, at its speed, a gap behind it."""
        other_speed = target.other_speed if target.other_speed is not None else target.current_speed
        return route(weight=0.5) + speed(other_speed, 1) + avoid(2.0)
