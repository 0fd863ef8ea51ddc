"""Guidance costs and terms: what a cost computes, which agents it steers, and when it applies.

A cost maps rolled-out states [S, A, T, 4] (x, y, heading, speed in the scene frame, 10 Hz; S
candidates of one scene) to one value per candidate to MINIMISE, differentiably. A term is a cost
with a weight and a schedule over the denoising steps (paper 'Controllable Behavior via Diffusion
Guidance'). Costs take agent slots (model agent indices) and other parameters in `__init__`.

See docs/simulation.md.
"""

from __future__ import annotations

import math
import operator
from abc import ABC, abstractmethod
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import ClassVar, Literal

import torch
from torch import Tensor

from langtraj.errors import InputError
from langtraj.guidance.scene import GuidanceScene
from langtraj.model.diffusion import timestep_sequence
from langtraj.registry import Registry

ScheduleFn = Callable[[Tensor, int], Tensor]
"""(k long [B], num_steps K) -> bool [B]: the rows whose denoising step k the term applies at."""
Schedule = Literal["all", "early", "late"] | ScheduleFn
"""'all' steps, the 'early' (noisier, k >= K/2) or the 'late' (k < K/2) half, or a function."""


class GuidanceCost(ABC):
    """A differentiable cost over rolled-out states; `slots` are the agents it steers (None: all)."""

    name: ClassVar[str]
    scene_wide: ClassVar[bool] = False
    """True for costs that take no parameters and steer every agent: `langtraj simulate --guidance` offers them."""
    slots: tuple[int, ...] | None = None

    @abstractmethod
    def __call__(self, states: Tensor, scene: GuidanceScene) -> Tensor:
        """states [S, A, T, 4] -> cost [S] (to minimise), differentiable in `states`."""

    def agents(self, num_agents: int) -> Tensor:
        """bool [num_agents]: the agents whose actions get this cost's gradient."""
        if self.slots is None:
            return torch.ones(num_agents, dtype=torch.bool)
        check_slots(self.name, self.slots, num_agents)
        mask = torch.zeros(num_agents, dtype=torch.bool)
        mask[list(self.slots)] = True
        return mask

    def steered(self, states: Tensor, scene: GuidanceScene) -> Tensor:
        """bool [A] on the states' device: steered agents that are valid in the scene."""
        check_states(self.name, states, scene)
        return self.agents(states.shape[1]).to(states.device) & scene.agent_valid.to(states.device)


GUIDANCE: Registry[GuidanceCost] = Registry("guidance cost")
"""The guidance costs by name; the built-in ones (`langtraj.guidance.costs`) register when the package loads."""


@dataclass(frozen=True)
class GuidanceTerm:
    """`weight` x `cost`, applied at the denoising steps `schedule` selects."""

    cost: GuidanceCost
    weight: float = 1.0
    schedule: Schedule = "all"

    def __post_init__(self) -> None:
        if not math.isfinite(self.weight) or self.weight < 0:
            raise InputError(f"{self.cost.name}: weight must be finite and >= 0, got {self.weight}")
        if not callable(self.schedule) and self.schedule not in ("all", "early", "late"):
            raise InputError(f"{self.cost.name}: unknown schedule {self.schedule!r}; known: all, early, late")

    def active(self, k: Tensor, num_steps: int) -> Tensor:
        """bool [B]: rows whose denoising step k (long [B], 0 = the last, clean step) the term applies at."""
        if callable(self.schedule):
            return torch.as_tensor(self.schedule(k, num_steps), dtype=torch.bool, device=k.device).expand(k.shape)
        if self.schedule == "early":
            return 2 * k >= num_steps
        if self.schedule == "late":
            return 2 * k < num_steps
        return torch.ones_like(k, dtype=torch.bool)


@dataclass(frozen=True)
class FinalSteps:
    """A schedule (`ScheduleFn`) active at the last `count` of the timesteps a sampler visits with
    `sampler_steps` inference steps (`model.diffusion.timestep_sequence`): guidance where it shapes the
    sample most directly, at a fraction of its cost (docs/simulation.md, 'Guidance')."""

    count: int
    sampler_steps: int

    def __post_init__(self) -> None:
        if not 1 <= self.count <= self.sampler_steps:
            raise InputError(f"guided steps must be in [1, {self.sampler_steps}], got {self.count}")

    def __call__(self, k: Tensor, num_steps: int) -> Tensor:
        visited = timestep_sequence(num_steps, num_inference_steps=min(self.sampler_steps, num_steps))
        chosen = torch.tensor(visited[-self.count :], device=k.device)
        return torch.isin(k, chosen)


# ---------------------------------------------------------------- parameter checks shared by the costs


def as_slot(cost: str, value: int, what: str = "slot") -> int:
    """`value` as an agent slot; a negative or non-integer value raises InputError naming the cost."""
    try:
        index = operator.index(value)
    except TypeError:
        index = -1
    if isinstance(value, bool) or index < 0:
        raise InputError(f"{cost}: {what} must be a non-negative agent slot, got {value!r}")
    return index


def as_slots(cost: str, values: int | Iterable[int] | None, what: str = "slots") -> tuple[int, ...] | None:
    """Agent slots (one or many, duplicates dropped) or None for all; an empty list raises InputError."""
    if values is None:
        return None
    items = tuple(values) if isinstance(values, Iterable) else (values,)
    if not items:
        raise InputError(f"{cost}: {what} is empty; give at least one agent slot, or None for all")
    return tuple(dict.fromkeys(as_slot(cost, v, what) for v in items))


def check_slots(cost: str, slots: Iterable[int], num_agents: int) -> None:
    """Raise InputError when a slot is not one of `num_agents` agents."""
    bad = [s for s in slots if s >= num_agents]
    if bad:
        raise InputError(f"{cost}: agent slot {bad[0]} is out of range for {num_agents} agents")


def check_states(cost: str, states: Tensor, scene: GuidanceScene) -> None:
    """Raise InputError unless states are [S, A, T, 4] with the scene's A agents and T >= 1."""
    if states.ndim != 4 or states.shape[-1] != 4 or states.shape[2] < 1:
        raise InputError(f"{cost}: states must be [S, A, T, 4], got {tuple(states.shape)}")
    if states.shape[1] != scene.num_agents:
        raise InputError(f"{cost}: states have {states.shape[1]} agents, the scene {scene.num_agents}")


def window(cost: str, start: int, end: int | None) -> tuple[int, int | None]:
    """A checked step window [start, end) (end None: to the horizon's end)."""
    if start < 0 or (end is not None and end <= start):
        raise InputError(f"{cost}: need 0 <= start < end, got start={start}, end={end}")
    return int(start), None if end is None else int(end)


def in_window(cost: str, states: Tensor, start: int, end: int | None) -> Tensor:
    """states[:, :, start:end]; a window starting past the horizon raises InputError."""
    if start >= states.shape[2]:
        raise InputError(f"{cost}: window start {start} is past the horizon of {states.shape[2]} steps")
    return states[:, :, start:end]
