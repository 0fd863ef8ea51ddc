"""Synthetic observations for the planner tests: zeros of the observation space's shapes, a route, agents, lights."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from langtraj.env.spaces import NUM_ROUTE_POINTS, ROUTE_SPACING_M, AgentColumn, EgoColumn, observation_space

EGO_SIZE = (4.5, 2.0)


def straight_route() -> np.ndarray:
    """Points every 2 m along +x from the ego."""
    x = ROUTE_SPACING_M * np.arange(NUM_ROUTE_POINTS)
    return np.stack([x, np.zeros_like(x)], axis=1)


def left_curve(radius: float = 20.0) -> np.ndarray:
    """Points every 2 m along a circle turning left (centre at (0, radius)), starting at the ego heading +x."""
    angle = ROUTE_SPACING_M * np.arange(NUM_ROUTE_POINTS) / radius
    return np.stack([radius * np.sin(angle), radius * (1.0 - np.cos(angle))], axis=1)


def make_observation(
    *,
    speed: float = 10.0,
    pose: tuple[float, float, float] = (0.0, 0.0, 0.0),
    time: float = 0.0,
    route: np.ndarray | None = None,
    agents: Sequence[Sequence[float]] = (),
    agent_types: Sequence[int] | None = None,
    lights: Sequence[tuple[float, float, int]] = (),
    speed_limits: float | Sequence[float] = 0.0,
) -> dict[str, np.ndarray]:
    """An observation of an ego at world `pose` driving at `speed`: `route` [N <= 50, 2] (default straight along
    +x; an empty one leaves it invalid) with its `speed_limits` (m/s, one or per point; 0: none), `agents` rows
    (x, y, heading, vx, vy, length, width) in the ego frame and `lights` (x, y, state)."""
    space = observation_space()
    obs = {key: np.zeros(sub.shape, sub.dtype) for key, sub in space.spaces.items()}
    ego = obs["ego"]
    ego[[EgoColumn.X, EgoColumn.Y, EgoColumn.HEADING]] = pose
    ego[EgoColumn.SPEED], (ego[EgoColumn.LENGTH], ego[EgoColumn.WIDTH]) = speed, EGO_SIZE
    obs["time"][0] = time
    route = straight_route() if route is None else np.asarray(route)
    obs["route"][: len(route)] = route
    obs["route_valid"][: len(route)] = 1
    obs["route_speed_limit"][: len(route)] = speed_limits
    for i, row in enumerate(agents):  # rows listed in AgentColumn's order
        obs["agents"][i, list(AgentColumn)] = row
        obs["agents_id"][i] = 100 + i
        obs["agents_type"][i] = 1 if agent_types is None else agent_types[i]
        obs["agents_valid"][i] = 1
    for i, (x, y, state) in enumerate(lights):
        obs["lights"][i] = (x, y)
        obs["lights_state"][i] = state
        obs["lights_valid"][i] = 1
    return obs


def vehicle(x: float, y: float = 0.0, speed: float = 0.0, heading: float = 0.0) -> list[float]:
    """An agent row: a 4.5 x 2 m vehicle at (x, y) in the ego frame driving at `speed` along `heading`."""
    return [x, y, heading, speed * np.cos(heading), speed * np.sin(heading), 4.5, 2.0]
