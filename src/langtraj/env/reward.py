"""The environment's default reward (docs/testing.md, 'Reward'): progress along the route minus penalties for
collisions and leaving the road, per step, so reinforcement-learning users can train on it as it is."""

from __future__ import annotations

import math
from dataclasses import dataclass

from langtraj.errors import InputError


@dataclass(frozen=True)
class RewardConfig:
    """Weights of the per-step reward: `progress` per metre gained along the route, minus `collision` at a step
    where the ego overlaps another agent (`at_fault_collision` more when it caused it), minus `offroad` at a step
    off the road."""

    progress: float = 0.1
    collision: float = 5.0
    at_fault_collision: float = 5.0
    offroad: float = 1.0

    def __post_init__(self) -> None:
        for name in ("progress", "collision", "at_fault_collision", "offroad"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value)):
                raise InputError(f"must be a finite number, got {value!r}", where=f"reward.{name}")

    def reward(self, gained_m: float, collision: bool, at_fault: bool, offroad: bool) -> float:
        """The reward of one step."""
        return (
            self.progress * gained_m
            - self.collision * collision
            - self.at_fault_collision * (collision and at_fault)
            - self.offroad * offroad
        )
