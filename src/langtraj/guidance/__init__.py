"""Cost guidance for the diffusion sampler: differentiable costs over rolled-out states, the
reconstruction-guidance step, and the fixed CTG++-style library of costs per InterDrive label.
See docs/simulation.md."""

from langtraj.guidance.base import GUIDANCE, GuidanceCost, GuidanceTerm, Schedule
from langtraj.guidance.costs import (
    CollisionCost,
    GoalCost,
    HeadwayCost,
    KeepLaneCost,
    NoCollisionCost,
    OnRoadCost,
    TargetSpeedCost,
)
from langtraj.guidance.library import (
    INTERACTION_GUIDANCE,
    LABEL_GUIDANCE,
    PromptAgents,
    terms_for,
    terms_for_prompt,
)
from langtraj.guidance.route import RouteCost, StationCost
from langtraj.guidance.scene import GuidanceScene
from langtraj.guidance.step import reconstruction_guidance

__all__ = [
    "GUIDANCE",
    "INTERACTION_GUIDANCE",
    "LABEL_GUIDANCE",
    "CollisionCost",
    "GoalCost",
    "GuidanceCost",
    "GuidanceScene",
    "GuidanceTerm",
    "HeadwayCost",
    "KeepLaneCost",
    "NoCollisionCost",
    "OnRoadCost",
    "PromptAgents",
    "RouteCost",
    "Schedule",
    "StationCost",
    "TargetSpeedCost",
    "reconstruction_guidance",
    "terms_for",
    "terms_for_prompt",
]
