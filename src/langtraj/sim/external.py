"""Agents the simulation does not move (an ego under test, docs/testing.md): the model sees them as any other
agent, but their future is not the model's to choose. Guidance and candidate selection judge the other agents
against a forecast of them instead of against the model's own guess of what they will do: constant speed and
heading from their current state, as the WOSAC constant-velocity baseline forecasts (docs/simulation.md,
'External agents')."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
from torch import Tensor

from langtraj.scenario.model import STEP_SECONDS
from langtraj.sim.world import SimWorld


def forecast(current: Tensor, steps: int, accel: Tensor | None = None, dt: float = STEP_SECONDS) -> Tensor:
    """States [..., steps, 4] (x, y, heading, speed) after `current` [..., 4] at constant heading and acceleration
    `accel` [...] (m/s^2; None: constant speed), the speed held at 0 once it gets there (a braking car stops)."""
    x, y, heading, speed = current.unbind(-1)
    t = torch.arange(1, steps + 1, dtype=current.dtype, device=current.device) * dt
    v0 = speed[..., None].clamp(min=0)
    a = torch.zeros_like(v0) if accel is None else accel[..., None].to(current.dtype)
    v = (v0 + a * t).clamp(min=0)
    stop = torch.where(a < 0, v0 / (-a).clamp(min=1e-9), torch.full_like(v0, torch.inf))  # when it stops
    moving = torch.minimum(t, stop)
    travelled = v0 * moving + 0.5 * a * moving**2
    return torch.stack(
        [
            x[..., None] + travelled * torch.cos(heading)[..., None],
            y[..., None] + travelled * torch.sin(heading)[..., None],
            heading[..., None].expand_as(travelled),
            v,
        ],
        dim=-1,
    )


def pin_external(states: Tensor, current: Tensor, slots: Sequence[int], accel: Tensor | None = None) -> Tensor:
    """`states` [..., A, T, 4] with the agents in `slots` replaced by their forecast from `current` [..., A, 4] and
    their accelerations `accel` [..., len(slots)] (both broadcast over `states`' leading axes). Without slots,
    `states` itself."""
    if not slots:
        return states
    index = torch.as_tensor(list(slots), device=states.device)
    ahead = forecast(current.index_select(-2, index).to(states.dtype), states.shape[-2], accel)
    out = states.clone()
    out[..., index, :, :] = ahead.expand(*states.shape[:-3], len(slots), *states.shape[-2:])
    return out


def external_acceleration(world: SimWorld, slots: Sequence[int], step: int, rollouts: Sequence[int]) -> Tensor:
    """The acceleration [R, len(slots)] (m/s^2) of the driven agents in `slots` over the step before `step` in
    `rollouts` (0 at the first step of the log)."""
    if not slots or step < 1:
        return torch.zeros(len(rollouts), len(slots), dtype=torch.float32)
    rows = world.driven[list(slots)]
    now = world.current(step, rows)[list(rollouts), :, 3]
    before = world.current(step - 1, rows)[list(rollouts), :, 3]
    known = world.valid[list(rollouts)][:, rows, step - 1]
    return torch.as_tensor(np.where(known, (now - before) / STEP_SECONDS, 0.0), dtype=torch.float32)


CLEARANCE_ITERATIONS = 1
"""Gradient steps of the clearance guidance per denoising step (two, a prompt's, cleared no more seeds of the
constructed follower scene: 8 of 8 either way, docs/simulation.md, 'External agents')."""


def accelerations_only(x: Tensor) -> Tensor:
    """Unicycle actions [..., 2] whose yaw rates are detached: guidance through them changes accelerations alone."""
    return torch.stack([x[..., 0], x[..., 1].detach()], dim=-1)
