"""Open-loop measures used in validation and experiments: minADE over samples, constant velocity."""

from __future__ import annotations

import torch
from torch import Tensor

from langtraj.model.batch import SceneBatch


def ade_per_sample(states: Tensor, batch: SceneBatch) -> tuple[Tensor, Tensor]:
    """ADE [S, B, A] of sampled states [S, B, A, T, >=2] against the logged future, over valid steps,
    and which agents have any valid future step (bool [B, A])."""
    valid = batch.future_valid & batch.agent_valid[..., None]
    count = valid.sum(-1)
    err = torch.linalg.norm(states[..., :2] - batch.future[None, ..., :2], dim=-1)
    ade = (err * valid).sum(-1) / count.clamp(min=1)
    return ade, count > 0


def min_ade(states: Tensor, batch: SceneBatch, agents: Tensor | None = None) -> tuple[Tensor, Tensor]:
    """Sum of per-agent minADE over samples and the number of agents counted, for the agents selected by
    `agents` (bool [B, A]; default every agent with a valid future)."""
    ade, has_future = ade_per_sample(states, batch)
    chosen = has_future if agents is None else has_future & agents
    best = ade.min(dim=0).values
    return (best * chosen).sum(), chosen.sum()


def constant_velocity(batch: SceneBatch, steps: int) -> Tensor:
    """States [1, B, A, T, 4] keeping each agent's current speed and heading (scene frame)."""
    x, y, heading, speed = batch.current_state.unbind(-1)
    t = torch.arange(1, steps + 1, device=x.device, dtype=x.dtype) * 0.1
    px = x[..., None] + speed[..., None] * torch.cos(heading)[..., None] * t
    py = y[..., None] + speed[..., None] * torch.sin(heading)[..., None] * t
    return torch.stack([px, py, heading[..., None].expand_as(px), speed[..., None].expand_as(px)], -1)[None]
