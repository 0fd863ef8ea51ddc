"""How the ego moves (docs/testing.md, 'Actions'): a control action through the model's unicycle for one 0.1-s
step; a trajectory action through a tracker over its whole 1-s horizon (`track`): the acceleration that best fits
its speed profile and pure pursuit of a pose ahead, as a planner's trajectory is followed in nuPlan's closed loop
(there by an LQR tracker)."""

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


LOOKAHEAD_S = 0.5
"""Pure pursuit aims at the first pose at least this far ahead in time at the ego's speed ..."""
LOOKAHEAD_MIN_M = 2.0
"""... and at least this far away (m); the last pose when none is."""


def track(pose: np.ndarray, trajectory: np.ndarray) -> np.ndarray:
    """The control (acceleration, yaw rate) that follows `trajectory` [N, 3] (x, y, heading in the ego frame, poses
    every 0.1 s from the next step) from the unicycle at `pose` (x, y, heading, speed; world), over the whole horizon:

    - the acceleration is the least-squares fit of the poses' distances along the trajectory by the unicycle held at
      one acceleration (its semi-implicit update: after k steps it has covered k v dt + a dt^2 k (k + 1) / 2), so a
      profile of constant acceleration is followed exactly and later poses weigh in;
    - the yaw rate is pure pursuit of the pose `LOOKAHEAD_S` (at least `LOOKAHEAD_MIN_M`) ahead, pose k: the unicycle
      held at yaw rate w reaches it along a chord at (k + 1) w dt / 2 to its heading, so w = 2 atan2(y, x) /
      ((k + 1) dt), exact for arcs the unicycle drives and steering back onto a trajectory it is beside; where the
      trajectory stays within a few centimetres, the ego turns toward its last pose's heading.

    The unicycle's bounds clip both (`step_unicycle`)."""
    poses = np.asarray(trajectory, np.float64)
    v, dt = float(pose[3]), STEP_SECONDS
    k = np.arange(1, len(poses) + 1, dtype=np.float64)
    along = np.cumsum(np.hypot(*np.diff(np.vstack([np.zeros(2), poses[:, :2]]), axis=0).T))
    gain = dt * dt * k * (k + 1) / 2
    accel = float(gain @ (along - k * v * dt) / (gain @ gain))
    speed = max(v + accel * dt, 0.0)
    distance = np.hypot(poses[:, 0], poses[:, 1])
    if along[-1] < 0.05:  # standing: turn toward the last pose's heading over the horizon
        return np.array([accel, float(wrap_angle(poses[-1, 2])) / (len(poses) * dt)], np.float64)
    reach = max(LOOKAHEAD_S * speed, LOOKAHEAD_MIN_M)
    ahead = np.flatnonzero(distance >= reach)
    at = int(ahead[0]) if ahead.size else len(poses) - 1
    x, y = poses[at, :2]
    return np.array([accel, 2.0 * math.atan2(y, x) / ((at + 2) * dt)], np.float64)
