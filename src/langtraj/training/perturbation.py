"""Recovery training: agents' observed pasts moved off their logged path, their targets kept, so the
model learns to steer back to the lane (ChauffeurNet-style perturbations; not in the paper).

Closed-loop simulation drifts: a small yaw-rate error puts a car half a metre off its lane within
seconds, a state that logged traffic never shows the model. Moving an agent's whole past rigidly
(sideways and turned about its current position) keeps the past self-consistent, while the inverse
dynamics fit the logged future from the moved current state: a path back. See docs/model.md,
'Recovery training'.
"""

from __future__ import annotations

from dataclasses import replace

import torch

from langtraj.model.batch import SceneBatch
from langtraj.model.scene_encoder import rotate
from langtraj.training.config import PerturbationConfig


def perturb_pasts(
    batch: SceneBatch, config: PerturbationConfig, generator: torch.Generator | None = None
) -> SceneBatch:
    """The batch with the past of a random `config.probability` of its moving agents (current speed at
    least `config.min_speed`, with a logged future) shifted sideways by U(-lateral_m, lateral_m) and
    turned by U(-heading_rad, heading_rad) about its current position; futures unchanged. The draws come
    from `generator` (default: torch's global one, which training seeds per step)."""
    if config.probability <= 0:
        return batch
    current = batch.current_state
    b, a = current.shape[:2]
    draw = torch.rand((b, a, 3), generator=generator).to(current)
    moving = batch.agent_valid & (current[..., 3] >= config.min_speed) & batch.future_valid.any(-1)
    chosen = moving & (draw[..., 0] < config.probability)
    turn = torch.where(chosen, (2 * draw[..., 1] - 1) * config.heading_rad, torch.zeros_like(draw[..., 1]))
    side = torch.where(chosen, (2 * draw[..., 2] - 1) * config.lateral_m, torch.zeros_like(draw[..., 2]))
    heading = current[..., 2]
    shift = side[..., None] * torch.stack([-torch.sin(heading), torch.cos(heading)], -1)  # along the left normal
    centre = current[..., :2]

    history = batch.agent_history
    valid = batch.history_valid[..., None]
    moved_xy = centre[:, :, None] + rotate(history[..., 0:2] - centre[:, :, None], turn[..., None]) + shift[:, :, None]
    moved = torch.cat(
        [
            moved_xy,
            rotate(history[..., 2:4], turn[..., None]),  # (cos, sin) of the heading turn as a vector
            rotate(history[..., 4:6], turn[..., None]),
            history[..., 6:7],
        ],
        dim=-1,
    )
    history = torch.where(valid & chosen[..., None, None], moved, history)
    state = torch.cat([centre + shift, (heading + turn)[..., None], current[..., 3:4]], dim=-1)
    # The targets are refitted from the moved current states (the stored ones start from the logged state).
    return replace(
        batch,
        agent_history=history,
        current_state=torch.where(chosen[..., None], state, current),
        target_actions=None,
        target_valid=None,
    )
