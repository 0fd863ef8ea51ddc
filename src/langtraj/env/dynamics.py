"""How the ego moves (docs/testing.md, 'Actions'): a control action through the model's unicycle for one 0.1-s
step; a trajectory action through a tracker that aims the unicycle at the trajectory's first pose."""

from __future__ import annotations

import math

import numpy as np
import torch

from langtraj.angles import wrap_angle
from langtraj.env import spaces
from langtraj.model.dynamics import Unicycle
from langtraj.scenario.model import STEP_SECONDS

_UNICYCLE = Unicycle(steps_per_action=1, dt=STEP_SECONDS, max_accel=spaces.MAX_ACCEL, max_yaw_rate=spaces.MAX_YAW_RATE)


def step_unicycle(pose: np.ndarray, control: np.ndarray, max_curvature: float = math.inf) -> np.ndarray:
    """The pose (x, y, heading, speed) 0.1 s after `pose` under `control` (acceleration, yaw rate), clipped to the
    unicycle's bounds; a yaw rate beyond `max_curvature` x speed is cut to it (a car turns only while it moves)."""
    initial = torch.as_tensor(pose, dtype=torch.float64)[None]
    action = _UNICYCLE.clip(torch.as_tensor(control, dtype=torch.float64))[None, None]
    limit = torch.tensor([max_curvature], dtype=torch.float64)
    return _UNICYCLE(initial, action, limit)[0, 0].numpy()


def track(pose: np.ndarray, trajectory: np.ndarray) -> np.ndarray:
    """The control that takes the unicycle at `pose` (x, y, heading, speed; world) to the first pose of
    `trajectory` [N, 3] (x, y, heading in the ego frame): the speed and heading that cover the displacement in one
    step (the unicycle's semi-implicit update moves along the new heading at the new speed), so a trajectory the
    unicycle can drive is followed exactly; where it stays put, it turns toward the pose's heading."""
    dx, dy, heading = (float(v) for v in trajectory[0])
    distance = math.hypot(dx, dy)
    speed = distance / STEP_SECONDS
    turn = math.atan2(dy, dx) if distance > 1e-3 else heading
    accel = (speed - float(pose[3])) / STEP_SECONDS
    return np.array([accel, float(wrap_angle(turn)) / STEP_SECONDS], np.float64)
