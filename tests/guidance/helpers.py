"""Small scenes and trajectories for the guidance tests, built in memory."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import torch
from torch import Tensor

from langtraj.guidance import GuidanceScene


def make_scene(
    num_agents: int = 2,
    *,
    size: tuple[float, float] = (4.5, 2.0),
    road_edges: Sequence[Sequence[Sequence[float]]] = (),
    lanes: Sequence[Sequence[Sequence[float]]] = (),
    valid: Sequence[bool] | None = None,
) -> GuidanceScene:
    """A scene of `num_agents` agents of one size, with the given edge segments and lane polylines."""
    points = max((len(lane) for lane in lanes), default=2)
    lane_xy = torch.zeros(len(lanes), points, 2)
    lane_valid = torch.zeros(len(lanes), points, dtype=torch.bool)
    for row, lane in enumerate(lanes):
        lane_xy[row, : len(lane)] = torch.tensor(lane, dtype=torch.float32)
        lane_valid[row, : len(lane)] = True
    return GuidanceScene(
        road_edges=torch.tensor(road_edges, dtype=torch.float32).reshape(-1, 2, 2),
        lanes=lane_xy,
        lane_valid=lane_valid,
        agent_size=torch.tensor([size] * num_agents, dtype=torch.float32),
        agent_valid=torch.ones(num_agents, dtype=torch.bool) if valid is None else torch.tensor(valid),
    )


def standing(positions: Sequence[Sequence[float]], steps: int = 10, speed: float = 0.0) -> Tensor:
    """States [1, A, steps, 4] of agents at `positions` (x, y[, heading]) for every step."""
    rows = []
    for pos in positions:
        heading = pos[2] if len(pos) > 2 else 0.0
        rows.append(torch.tensor([pos[0], pos[1], heading, speed]).expand(steps, 4))
    return torch.stack(rows)[None].clone()


def cost_gradient(cost, states: Tensor, scene: GuidanceScene) -> tuple[Tensor, Tensor]:
    """The cost [S] and its gradient with respect to `states`."""
    states = states.clone().requires_grad_(True)
    value = cost(states, scene)
    (grad,) = torch.autograd.grad(value.sum(), states)
    return value.detach(), grad


def displacement_rollout(start: Tensor) -> Callable[[Tensor], Tensor]:
    """A simple differentiable rollout: actions [S, A, N, 2] are per-step displacements from `start`
    [A, 2]; heading 0, speed = the displacement's x (m per step)."""

    def rollout(x: Tensor) -> Tensor:
        xy = start[None, :, None, :] + torch.cumsum(x, dim=2)
        return torch.cat([xy, torch.zeros_like(x[..., :1]), x[..., :1]], dim=-1)

    return rollout


def crowd(
    num_agents: int, candidates: int, rollouts: int, steps: int, seed: int, road_edges: Tensor | None = None
) -> tuple[Tensor, GuidanceScene]:
    """Candidates [M, R, A, T, 4] of agents of mixed sizes crowded into 40 x 20 m, turning and jittering
    (many near misses and overlaps), and their scene with `road_edges` [E, 2, 2] (the last agent is
    padding)."""
    g = torch.Generator().manual_seed(seed)
    start = torch.rand(num_agents, 2, generator=g) * torch.tensor([40.0, 20.0])
    heading = torch.rand(candidates, rollouts, num_agents, 1, generator=g) * 2 * math.pi
    turn = torch.randn(candidates, rollouts, num_agents, 1, generator=g) * 0.05
    headings = heading + turn * torch.arange(steps)
    speed = torch.rand(candidates, rollouts, num_agents, 1, generator=g) * 3.0
    step = torch.stack([torch.cos(headings), torch.sin(headings)], -1) * speed[..., None] * 0.1
    xy = (
        start[None, None, :, None]
        + step.cumsum(3)
        + torch.randn(candidates, rollouts, num_agents, steps, 2, generator=g) * 0.05
    )
    states = torch.cat([xy, headings[..., None], speed[..., None].expand(-1, -1, -1, steps, 1)], -1)
    valid = torch.ones(num_agents, dtype=torch.bool)
    valid[-1] = False
    size = torch.rand(num_agents, 2, generator=g) * torch.tensor([4.0, 1.2]) + torch.tensor([0.6, 0.6])
    scene = GuidanceScene(
        road_edges=torch.zeros(0, 2, 2) if road_edges is None else road_edges,
        lanes=torch.zeros(0, 2, 2),
        lane_valid=torch.zeros(0, 2, dtype=torch.bool),
        agent_size=size,
        agent_valid=valid,
    )
    return states, scene
