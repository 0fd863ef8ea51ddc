"""Whether simulated traffic flows as its log does (docs/metrics.md, 'Traffic flow'): of the vehicles moving at the
current step and logged over the whole future, how fast they drive against their log (the ratio of the distances
driven in 8 s) and how many end the 8 s stopped against the log's share. WOSAC's speed likelihoods cannot tell a
scene whose moving traffic crawls at half its logged speed from one that keeps going: these two figures do.

The log is read only here, to score rollouts that were simulated without it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from langtraj.roads.position import current_speeds
from langtraj.rollouts.container import Rollouts
from langtraj.rollouts.validation import check_rollouts
from langtraj.scenario.model import STEP_SECONDS, Scenario
from langtraj.scenario.types import AgentType, StateField

MOVING_MPS = 2.0
"""A vehicle moves at the current step at this speed (m/s) or more: parked and queued cars are not traffic flow."""
STOPPED_MPS = 0.5
"""A vehicle ends stopped when its mean speed over the last `END_STEPS` steps is below this (m/s)."""
END_STEPS = 5
"""The steps (0.5 s at 10 Hz) a vehicle's end speed is measured over."""


@dataclass(frozen=True)
class FlowResult:
    """The flow figures of one scene's rollouts: `vehicles` scored; `speed_ratio` the simulated distance over the
    logged one, pooled over them and the rollouts (1: as fast as the log); `median_ratio` the median vehicle's own
    ratio (its rollouts pooled); `stopped` the share of (rollout, vehicle) pairs ending stopped and `stopped_log`
    the share of the vehicles ending stopped in the log. NaN figures where no vehicle qualifies."""

    vehicles: int
    speed_ratio: float
    median_ratio: float
    stopped: float
    stopped_log: float

    def as_dict(self) -> dict[str, float]:
        return {
            "flow_vehicles": float(self.vehicles),
            "speed_ratio": self.speed_ratio,
            "median_speed_ratio": self.median_ratio,
            "stopped": self.stopped,
            "stopped_log": self.stopped_log,
        }


FLOW_KEYS = ("flow_vehicles", "speed_ratio", "median_speed_ratio", "stopped", "stopped_log")
"""The keys of `FlowResult.as_dict`."""


def moving_vehicles(scenario: Scenario, rollouts: Rollouts) -> tuple[np.ndarray, np.ndarray]:
    """The rollout columns and scenario tracks of the vehicles that move at the current step (`MOVING_MPS`, by the one
    speed rule, `roads.position.current_speeds`) and are logged at it and over the whole simulated future (their log is
    the yardstick)."""
    agents, now, steps = scenario.agents, scenario.current_index, rollouts.num_steps
    tracks = check_rollouts(scenario, rollouts)
    future = agents.valid[tracks, now : now + steps + 1]
    logged = future.shape[1] == steps + 1 and future.all(axis=1)
    moving = current_speeds(scenario, tracks) >= MOVING_MPS
    vehicle = agents.types[tracks] == int(AgentType.VEHICLE)
    keep = np.flatnonzero(logged & moving & vehicle)
    return keep, tracks[keep]


def _driven(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The distance driven over every step of paths [..., T + 1] (the current position first), and the mean speed over
    the last `END_STEPS` steps (m/s)."""
    step = np.hypot(np.diff(x, axis=-1), np.diff(y, axis=-1))
    return step.sum(axis=-1), step[..., -END_STEPS:].sum(axis=-1) / (END_STEPS * STEP_SECONDS)


def traffic_flow(scenario: Scenario, rollouts: Rollouts) -> FlowResult:
    """The flow figures (`FlowResult`) of `rollouts` of `scenario` against its log."""
    columns, tracks = moving_vehicles(scenario, rollouts)
    if not len(columns):
        return FlowResult(0, math.nan, math.nan, math.nan, math.nan)
    now, steps = scenario.current_index, rollouts.num_steps
    states = scenario.agents.states[tracks, now : now + steps + 1]
    log_distance, log_end = _driven(states[..., StateField.X], states[..., StateField.Y])
    shape = (rollouts.num_rollouts, len(columns), 1)  # the current position, before every rollout's first step
    x, y = (
        np.concatenate([np.broadcast_to(states[:, :1, field], shape), path[:, columns]], axis=-1).astype(np.float64)
        for field, path in ((StateField.X, rollouts.x), (StateField.Y, rollouts.y))
    )
    distance, end = _driven(x, y)
    per_vehicle = distance.mean(axis=0) / np.maximum(log_distance, 1e-6)
    return FlowResult(
        vehicles=len(columns),
        speed_ratio=float(distance.mean(axis=0).sum() / max(log_distance.sum(), 1e-6)),
        median_ratio=float(np.median(per_vehicle)),
        stopped=float((end < STOPPED_MPS).mean()),
        stopped_log=float((log_end < STOPPED_MPS).mean()),
    )
