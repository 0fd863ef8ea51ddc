"""Synthetic scenes of a preset's full size for the training benchmarks (`train_memory.py`, `train_speed.py`):
every agent and map slot filled with plausible random geometry, so figures are an upper bound for real data."""

from __future__ import annotations

import math

import torch


def synthetic_batch(
    config,
    batch_size: int,
    seed: int = 0,
    agents: int | None = None,
    text_fraction: float | None = None,
    sentence: str | None = None,
    targets: bool = True,
):
    """A full batch of the preset's sizes: agents on a square of the map radius driving straight at 0-15
    m/s, straight map pieces of 2-m spacing, and in stage 2 a distinct sentence for the data's
    `heuristic_label_fraction` of each scene's agents (text dropout off: the most sentences a step meets).
    `agents` overrides the preset's `max_agents` (a scene to sample), `text_fraction` the share of agents with a
    sentence, and `sentence` gives them all that one sentence (the text encoder then encodes it once). With
    `targets` the batch carries its target actions, as batches from a feature store do (`model.targets`; code
    from before stored targets gets none)."""
    from langtraj.model.batch import AGENT_HISTORY_FEATURES, SceneBatch

    data, model = config.data, config.model
    g = torch.Generator().manual_seed(seed)
    b, a, m, p, h, f = (
        batch_size, agents or data.max_agents, data.max_polylines, data.points_per_polyline, model.history_steps,
        data.future_steps,
    )  # fmt: skip
    half = data.map_radius / 2
    pos = torch.rand(b, a, 2, generator=g) * 2 * half - half
    heading = torch.rand(b, a, generator=g) * 2 * math.pi - math.pi
    speed = torch.rand(b, a, generator=g) * 15
    direction = torch.stack([torch.cos(heading), torch.sin(heading)], -1)
    t = torch.arange(-h + 1, f + 1, dtype=torch.float32) * 0.1
    track = pos[:, :, None] + direction[:, :, None] * (speed[..., None, None] * t[:, None])
    history = torch.zeros(b, a, h, AGENT_HISTORY_FEATURES)
    history[..., 0:2] = track[:, :, :h]
    history[..., 2:4] = direction[:, :, None]
    history[..., 4:6] = (direction * speed[..., None])[:, :, None]
    history[..., 6] = 1
    start = torch.rand(b, m, 1, 2, generator=g) * 2 * half - half
    angle = torch.rand(b, m, 1, generator=g) * 2 * math.pi
    steps = torch.arange(p, dtype=torch.float32)[None, None, :, None] * 2.0
    fraction = data.heuristic_label_fraction if text_fraction is None else text_fraction
    texted = max(1, round(a * fraction)) if model.use_text else 0
    text = [[(sentence or f"scene {i}: agent {j} yields") if j < texted else None for j in range(a)] for i in range(b)]
    batch = SceneBatch(
        agent_history=history,
        history_valid=torch.ones(b, a, h, dtype=torch.bool),
        agent_type=torch.ones(b, a, dtype=torch.long),
        agent_size=torch.tensor([4.5, 2.0]).expand(b, a, 2).clone(),
        agent_valid=torch.ones(b, a, dtype=torch.bool),
        current_state=torch.cat([pos, heading[..., None], speed[..., None]], -1),
        future=torch.cat([track[:, :, h:], heading[..., None, None].expand(b, a, f, 1)], -1),
        future_valid=torch.ones(b, a, f, dtype=torch.bool),
        map_points=start + steps * torch.stack([torch.cos(angle), torch.sin(angle)], -1),
        map_valid=torch.ones(b, m, p, dtype=torch.bool),
        map_type=torch.full((b, m), 2, dtype=torch.long),
        text=text,
        interaction_labelled=torch.ones(b, dtype=torch.bool),
        origin=torch.zeros(b, 3),
        agent_id=torch.arange(a).expand(b, a).clone(),
        scenario_id=[f"bench{i}" for i in range(b)],
    )
    return with_targets(batch, data.future_steps, getattr(data, "dynamics", "unicycle")) if targets else batch


def with_targets(batch, future_steps: int, dynamics_name: str = "unicycle"):
    """`batch` with the target actions a feature store would hold for it, where this code stores them."""
    from dataclasses import fields, replace

    if "target_actions" not in {f.name for f in fields(batch)}:
        return batch  # code from before stored targets (a baseline checkout)
    from langtraj.model.dynamics import DYNAMICS
    from langtraj.model.targets import fit_actions

    dynamics = DYNAMICS.create(dynamics_name)
    actions, valid = fit_actions(
        dynamics, batch.current_state, batch.future, batch.future_valid, batch.agent_valid,
        future_steps // dynamics.steps_per_action,
    )  # fmt: skip
    return replace(batch, target_actions=actions, target_valid=valid)
