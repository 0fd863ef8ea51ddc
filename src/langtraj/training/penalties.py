"""Scene penalties on the predicted clean trajectory: leaving the road, and agents overlapping.

The denoising loss only pulls a prediction toward its log; an error of 0.7 m sideways costs it little but
leaves a SUMO road, and two agents' errors can put them on top of each other. These terms price exactly
that, with the differentiable geometry guidance steers by (`guidance.costs`), on the map pieces and agents
the model sees. See docs/model.md, 'Scene penalties'.
"""

from __future__ import annotations

import torch
from torch import Tensor

from langtraj.guidance.costs import NoCollisionCost, signed_edge_distance
from langtraj.guidance.scene import GuidanceScene
from langtraj.model.batch import SceneBatch
from langtraj.scenario.types import AgentType
from langtraj.training.config import PenaltyConfig


def _huber(excess: Tensor) -> Tensor:
    """x^2 / 2 up to 1 m, then linear: one far-off point (a junction's gap between edges) does not dominate."""
    return torch.nn.functional.huber_loss(excess, torch.zeros_like(excess), reduction="none", delta=1.0)


def batch_scenes(batch: SceneBatch) -> list[GuidanceScene]:
    """Each row's map pieces and agents as guidance geometry (`GuidanceScene.from_batch`), built once per batch."""
    return [GuidanceScene.from_batch(batch, row) for row in range(batch.batch_size)]


def road_penalty(
    batch: SceneBatch,
    states: Tensor,
    margin: float,
    weight: Tensor | None = None,
    scenes: list[GuidanceScene] | None = None,
) -> Tensor:
    """Weighted mean over (valid vehicle, valid future step) of huber(relu(s_pred - max(s_log, -margin))),
    where s is the signed distance to the nearest road edge (positive off the road): zero wherever the
    prediction is no further out than the log or than `margin` m inside the edge, so the log itself never
    pays (also where the map crop or a parked car puts the log near or past an edge); a scene without road edges
    costs nothing. `states` [B, A, T, >= 2]; `weight` [B]: each scene's weight (default 1); `scenes`: `batch_scenes`
    when the caller has them."""
    scenes = scenes or batch_scenes(batch)
    horizon = states.shape[2]
    mask = batch.future_valid[:, :, :horizon] & batch.agent_valid[..., None]
    mask = mask & (batch.agent_type == int(AgentType.VEHICLE))[..., None]
    total = states.new_zeros(())
    for row in range(batch.batch_size):
        keep = mask[row]
        if not keep.any():
            continue
        edges = scenes[row].road_edges.to(states)
        if edges.shape[0] == 0:
            continue
        predicted = signed_edge_distance(states[row, :, :, :2][keep], edges)
        with torch.no_grad():
            logged = signed_edge_distance(batch.future[row, :, :horizon, :2][keep].to(states), edges)
        past = _huber(torch.relu(predicted - logged.clamp(min=-margin))).sum()
        total = total + (past if weight is None else weight[row] * past)
    return total / mask.sum().clamp(min=1)


def contact_penalty(
    batch: SceneBatch, states: Tensor, weight: Tensor | None = None, scenes: list[GuidanceScene] | None = None
) -> Tensor:
    """Weighted mean over scenes of the disk overlap between their valid agents (`NoCollisionCost`: each
    overlapping pair's mean overlap over its overlapping steps, in [0, 1]), summed over pairs and divided by
    the number of agents: per agent, so it does not shrink in crowded scenes. `weight` [B] and `scenes` as
    `road_penalty`'s."""
    scenes = scenes or batch_scenes(batch)
    cost = NoCollisionCost()
    total = states.new_zeros(())
    for row in range(batch.batch_size):
        scene = scenes[row]
        agents = int(scene.agent_valid.sum())
        if agents < 2:
            continue
        value = cost(states[row : row + 1], scene)[0] * agents
        total = total + (value if weight is None else weight[row] * value)
    return total / batch.batch_size


def scene_penalties(
    batch: SceneBatch, states: Tensor, config: PenaltyConfig, signal: Tensor | None = None
) -> dict[str, Tensor]:
    """The active penalties by name ("road", "contact") and their weighted sum ("penalty"). `signal` [B]: each
    scene's abar_k, the share of its clean sample the network saw; a scene weighs that much, so the penalties
    shape the nearly clean predictions, not the posterior mean at pure noise (which may average two ways
    around an island and so leave the road, as it should)."""
    parts: dict[str, Tensor] = {}
    total = states.new_zeros(())
    scenes = batch_scenes(batch) if config.active else []
    if config.road_weight > 0:
        parts["road"] = road_penalty(batch, states, config.road_margin, signal, scenes)
        total = total + config.road_weight * parts["road"]
    if config.contact_weight > 0:
        parts["contact"] = contact_penalty(batch, states, signal, scenes)
        total = total + config.contact_weight * parts["contact"]
    return {**parts, "penalty": total}
