"""A `SceneBatch` built from tensors alone, for the model's tests (no scenario, no feature code)."""

from __future__ import annotations

import torch

from langtraj.model.batch import SceneBatch


def toy_batch(b: int = 2, a: int = 6, m: int = 10, p: int = 10, h: int = 11, f: int = 80) -> SceneBatch:
    """A fixed batch built from tensors alone (no scenario, no feature code): agents driving straight,
    straight map pieces, a sentence for each scene's first agent."""
    g = torch.Generator().manual_seed(7)
    pos = torch.rand(b, a, 2, generator=g) * 40 - 20
    heading = torch.rand(b, a, generator=g) * 0.6 - 0.3
    speed = torch.rand(b, a, generator=g) * 10
    d = torch.stack([heading.cos(), heading.sin()], -1)
    t = torch.arange(-h + 1, f + 1) * 0.1
    track = pos[:, :, None] + d[:, :, None] * (speed[..., None, None] * t[:, None])
    velocity = (d * speed[..., None])[:, :, None].expand(b, a, h, 2)
    history = torch.cat([track[:, :, :h], d[:, :, None].expand(b, a, h, 2), velocity, torch.ones(b, a, h, 1)], -1)
    start = torch.rand(b, m, 1, 2, generator=g) * 40 - 20
    return SceneBatch(
        agent_history=history,
        history_valid=torch.ones(b, a, h, dtype=torch.bool),
        agent_type=torch.ones(b, a, dtype=torch.long),
        agent_size=torch.tensor([4.5, 2.0]).expand(b, a, 2).clone(),
        agent_valid=torch.ones(b, a, dtype=torch.bool),
        current_state=torch.cat([pos, heading[..., None], speed[..., None]], -1),
        future=torch.cat([track[:, :, h:], heading[..., None, None].expand(b, a, f, 1)], -1),
        future_valid=torch.ones(b, a, f, dtype=torch.bool),
        map_points=start + torch.arange(p)[None, None, :, None] * 2.0 * torch.tensor([1.0, 0.0]),
        map_valid=torch.ones(b, m, p, dtype=torch.bool),
        map_type=torch.full((b, m), 2, dtype=torch.long),
        text=[["the target agent turns left" if j == 0 else None for j in range(a)] for _ in range(b)],
        interaction_labelled=torch.ones(b, dtype=torch.bool),
        origin=torch.zeros(b, 3),
        agent_id=torch.arange(a).expand(b, a).clone(),
        scenario_id=["toy"] * b,
    )
