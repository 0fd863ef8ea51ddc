"""Open-loop measures of validation, which the open-loop experiment shares (`experiments.open_loop`): minADE
over samples and constant velocity on a batch (docs/model.md)."""

from __future__ import annotations

import numpy as np
import torch
from torch import Tensor

from langtraj.model.batch import SceneBatch
from langtraj.rollouts.baselines import BASELINES
from langtraj.scenario.types import StateField


def ade_per_sample(states: Tensor, batch: SceneBatch) -> tuple[Tensor, Tensor]:
    """ADE [S, B, A] of sampled states [S, B, A, T, >=2] against the logged future's first T steps, over valid steps,
    and which agents have any valid future step (bool [B, A])."""
    horizon = states.shape[-2]  # a model may plan fewer than the logged steps (the closed-loop model: 4 s)
    valid = batch.future_valid[..., :horizon] & batch.agent_valid[..., None]
    count = valid.sum(-1)
    err = torch.linalg.norm(states[..., :2] - batch.future[None, :, :, :horizon, :2], dim=-1)
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
    """States [1, B, A, T, 4] (scene frame) by the WOSAC constant-velocity rule (`rollouts.baselines`),
    applied to each valid agent's last two history steps; padding agents stay at zeros."""
    rule = BASELINES.get("constant_velocity")()
    history = batch.agent_history.detach().cpu().double().numpy()  # [B, A, H, 7]
    valid = batch.history_valid.cpu().numpy() & batch.agent_valid.cpu().numpy()[..., None]
    real = batch.agent_valid.cpu().numpy()
    tracks = np.zeros((*history.shape[:3], len(StateField)))
    tracks[..., StateField.X : StateField.Y + 1] = history[..., :2]
    tracks[..., StateField.HEADING] = batch.current_state[..., 2].cpu().double().numpy()[..., None]
    tracks[..., StateField.VX : StateField.VY + 1] = history[..., 4:6]
    out = np.zeros((*real.shape, steps, 4))
    out[real] = rule.model_states(tracks[real], valid[real], history.shape[2] - 1, steps)  # [N, T, 4]
    return torch.as_tensor(out, dtype=batch.current_state.dtype, device=batch.current_state.device)[None]
