"""Rolling diffusion over a plan: noise levels that rise along the future (SceneDiffuser's amortized rollout,
Rolling Ahead Diffusion, arXiv 2502.09587).

A rolling plan holds each of its N actions at its own noise level: the actions executed next are nearly
clean, the last ones pure noise. One denoising call lowers every action by one rung, so the first `group`
actions become clean and are executed; the plan then shifts by `group` actions and takes fresh noise at the
end, which restores the levels it started from. A simulation therefore makes one network call per replan
after a cold start, and each call refines the plan it executes instead of drawing a new one.

Levels are 0-based indices of the model's K-step schedule (`model.diffusion`); -1 is clean. See
docs/model.md, 'Rolling plans'.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import torch
from torch import Tensor

from langtraj.errors import InputError
from langtraj.model.diffusion import DENOISING_STEP, DiffusionSchedule, Guidance, timestep_sequence

LevelDenoiser = Callable[[Tensor, Tensor], Tensor]
"""(x [B, A, N, 2] at per-action levels, levels long [N]) -> predicted x0 [B, A, N, 2]."""


@dataclass(frozen=True)
class RollingSchedule:
    """The per-action noise levels of a plan of `num_actions` actions that rolls by `group` actions at each call,
    on a `num_steps`-step schedule. Group g of G = num_actions / group holds level floor((g + 1) K / G) - 1 before
    a call (`before`: the last group at K - 1) and the level of group g - 1 after it (`after`: the first clean)."""

    num_actions: int
    num_steps: int
    group: int

    def __post_init__(self) -> None:
        if self.group < 1 or self.num_actions % self.group:
            raise InputError(
                f"must divide the {self.num_actions} actions and be >= 1, got {self.group}", where="rolling_group"
            )
        if self.num_steps < self.num_actions // self.group:
            raise InputError(
                f"a {self.num_steps}-step schedule has fewer levels than the plan's "
                f"{self.num_actions // self.group} groups",
                where="diffusion_steps",
            )

    @property
    def groups(self) -> int:
        return self.num_actions // self.group

    def before(self) -> Tensor:
        """Levels long [N] the plan holds when a call starts."""
        g = torch.arange(self.num_actions) // self.group
        return (g + 1) * self.num_steps // self.groups - 1

    def after(self) -> Tensor:
        """Levels long [N] after a call: each group at the level the group before it started from, the first clean."""
        before = self.before()
        return torch.cat([torch.full((self.group,), -1, dtype=torch.long), before[: -self.group]])

    def cold_start(self, inference_steps: int) -> list[tuple[Tensor, Tensor]]:
        """The (from, to) levels of the calls that take pure noise to `after`: the usual `inference_steps`-step
        sequence, each action stopping at its own level. The last call's `to` is `after`."""
        sequence = timestep_sequence(self.num_steps, num_inference_steps=inference_steps) + [-1]
        after = self.after()
        levels = torch.full((self.num_actions,), sequence[0], dtype=torch.long)
        calls = []
        for t in sequence[1:]:
            target = torch.maximum(torch.full_like(after, t), after)
            calls.append((levels, target))
            levels = target
        return calls

    def training_levels(self, batch: int, generator: torch.Generator | None = None) -> Tensor:
        """Levels long [batch, N] to train at: `before` shifted by up to half a rung either way (so the network
        sees the neighbourhood of each rung), then raised to a floor drawn in [-1, K) (a cold start's calls hold
        every action above the level the sequence has reached)."""
        half = self.num_steps // (2 * self.groups)
        shift = torch.randint(-half, half + 1, (batch, 1), generator=generator)
        floor = torch.randint(-1, self.num_steps, (batch, 1), generator=generator)
        levels = torch.maximum(self.before()[None] + shift, floor)
        return levels.clamp(0, self.num_steps - 1)


def denoise_between(
    denoise: LevelDenoiser,
    x: Tensor,
    levels: Tensor,
    target: Tensor,
    schedule: DiffusionSchedule,
    *,
    guidance: Guidance | None = None,
    guidance_step: int = 0,
) -> tuple[Tensor, Tensor]:
    """One network call on `x` [B, A, N, 2] whose actions sit at `levels` [N]: the x0 prediction (through
    `guidance`, called with step `guidance_step` for every row), and x stepped by deterministic DDIM to `target`
    [N] (each action at least as clean as before; equal levels stay put exactly, -1 returns x0). Returns (x, x0)."""
    if torch.any(target > levels):
        raise InputError("a rolling step cannot add noise", where="target")
    b, a, n, _ = x.shape
    with torch.profiler.record_function(DENOISING_STEP):
        x0 = denoise(x, levels.to(x.device))
    if guidance is not None:
        x0 = guidance(x0, torch.full((b,), guidance_step, dtype=torch.long, device=x.device), x)
    k = levels.to(x.device).expand(b, a, n)
    k_prev = target.to(x.device).expand(b, a, n)
    stepped = schedule.ddim_step(x0, x, k, k_prev)
    return torch.where((k == k_prev)[..., None], x, stepped), x0


def shift_plan(x: Tensor, group: int, fresh: Tensor) -> Tensor:
    """The plan `x` [B, A, N, 2] after its first `group` actions were executed: the rest moved to the front and
    `fresh` noise (of x's shape; its first `group` actions are used) at the end, at the top level."""
    return torch.cat([x[..., group:, :], fresh[..., :group, :]], dim=-2)
