"""Where an agent is on the lane graph at a scenario's current step (`AgentOnLane`), matched as the heuristic
labeler matches vehicles; the env finds its ego's lane and the targets their agent's with it."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from langtraj.roads.index import MapIndex
from langtraj.scenario.model import Scenario

LANE_MATCH_RADIUS = 3.0
"""Largest distance from a vehicle to the centerline of its matched lane (m); `HeuristicConfig.lane_match_radius`
defaults to it."""
LANE_MATCH_MAX_HEADING = math.radians(45.0)
"""Largest heading disagreement between a vehicle and its matched lane (rad); `HeuristicConfig` defaults to it."""


def current_speeds(scenario: Scenario, rows: np.ndarray | None = None) -> np.ndarray:
    """The speed (m/s) of each agent row (every row by default) at the scene's current step: from its positions since
    the first step it was seen in the last half second, as the labelers measure speed (some sources leave velocities
    at zero), else its recorded velocity."""
    agents, c = scenario.agents, scenario.current_index
    rows = np.arange(agents.num_agents) if rows is None else np.asarray(rows)
    speed = np.hypot(agents.velocity[rows, c, 0], agents.velocity[rows, c, 1]).astype(np.float64)
    dt = float(np.median(np.diff(scenario.timestamps))) if scenario.num_steps > 1 else 0.1
    for back in range(c - 1, max(c - 5, 0) - 1, -1):  # the earliest seen step wins: walk from the nearest back
        seen = agents.valid[rows, back]
        apart = agents.xy[rows, c] - agents.xy[rows, back]  # each row's own norm: the figures AgentOnLane had
        moved = np.array([float(np.linalg.norm(d)) for d in apart]) / ((c - back) * dt)
        speed = np.where(seen, moved, speed)
    return speed


@dataclass(frozen=True)
class AgentOnLane:
    """Where an agent is at the current step: its lane (index into the map index, -1 if none), station, speed."""

    lane: int
    station: float
    speed: float

    @classmethod
    def of(
        cls,
        scenario: Scenario,
        agent: int,
        index: MapIndex,
        *,
        radius: float = LANE_MATCH_RADIUS,
        max_heading: float = LANE_MATCH_MAX_HEADING,
    ) -> AgentOnLane:
        """Agent row `agent` matched to a lane within `radius` m and `max_heading` rad."""
        agents, c = scenario.agents, scenario.current_index
        speed = float(current_speeds(scenario, np.array([agent]))[0])
        if not index.has_lanes:
            return cls(-1, math.nan, speed)
        match = index.match_lanes(
            agents.xy[agent, c][None], agents.heading[agent, c : c + 1], radius=radius, max_heading_diff=max_heading
        )
        return cls(int(match.lane[0]), float(match.station[0]), speed)
