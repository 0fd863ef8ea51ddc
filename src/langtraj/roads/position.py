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
        speed = float(np.hypot(*agents.velocity[agent, c]))
        back = [t for t in range(c - 5, c) if t >= 0 and agents.valid[agent, t]]
        if back:  # from positions, as the labelers measure speed (some sources leave velocities at zero)
            step = float(np.median(np.diff(scenario.timestamps))) if scenario.num_steps > 1 else 0.1
            speed = float(np.linalg.norm(agents.xy[agent, c] - agents.xy[agent, back[0]])) / ((c - back[0]) * step)
        if not index.has_lanes:
            return cls(-1, math.nan, speed)
        match = index.match_lanes(
            agents.xy[agent, c][None], agents.heading[agent, c : c + 1], radius=radius, max_heading_diff=max_heading
        )
        return cls(int(match.lane[0]), float(match.station[0]), speed)
