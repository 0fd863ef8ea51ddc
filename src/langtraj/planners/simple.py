"""The reference planners that do not look at the road: constant velocity (the naive planner) and log replay (the
labelled baseline that reads the ego's logged future) (docs/testing.md, 'Built-in planners')."""

from __future__ import annotations

from typing import Any

import numpy as np

from langtraj.angles import wrap_angle
from langtraj.env.spaces import TRAJECTORY_POSES, EgoColumn
from langtraj.errors import InputError
from langtraj.frames import poses_to_frame
from langtraj.planners.base import PLANNERS, Planner
from langtraj.scenario.model import STEP_SECONDS


@PLANNERS.register
class ConstantVelocityPlanner(Planner):
    """Keeps its speed and heading whatever happens (action (0, 0)): the naive planner a test should catch, e.g.
    the one that ignores a cut-in."""

    name = "constant_velocity"
    action_kind = "control"

    def act(self, observation: dict[str, np.ndarray]) -> np.ndarray:
        return np.zeros(2, np.float32)


@PLANNERS.register
class LogReplayPlanner(Planner):
    """Drives the ego along its own logged future (`info["logged_ego"]`): a labelled baseline that reads the log,
    which a planner under test must not, so the suites' figures for it show what the logged driver would score.

    Each step answers the next `TRAJECTORY_POSES` logged poses (steps k+1 .. k+10 where k = round(time / step)), in
    the current ego frame; where the log has no state or has ended, the last valid logged pose before it is held
    (the ego's current pose where there is none), so the trajectory is always finite."""

    name = "log_replay"
    action_kind = "trajectory"
    reads_log = True

    def __init__(self) -> None:
        self.logged = np.full((0, 4), np.nan)

    def reset(self, observation: dict[str, np.ndarray], info: dict[str, Any]) -> None:
        """Keeps the ego's logged future (`logged_ego` [80, 4]: world x, y, heading, speed; NaN where unlogged),
        which the reset info must carry."""
        if "logged_ego" not in info:
            raise InputError("log replay needs the reset info's logged_ego (the ego's logged future)", where="info")
        logged = np.asarray(info["logged_ego"], np.float64)
        self.logged = logged.reshape(-1, logged.shape[-1]) if logged.size else np.full((0, 4), np.nan)

    def act(self, observation: dict[str, np.ndarray]) -> np.ndarray:
        ego = np.asarray(observation["ego"], np.float64)
        origin = (float(ego[EgoColumn.X]), float(ego[EgoColumn.Y]), float(ego[EgoColumn.HEADING]))
        step = round(float(np.asarray(observation["time"]).reshape(-1)[0]) / STEP_SECONDS)
        poses = self.logged[:, :3]
        usable = np.isfinite(poses).all(axis=1)
        before = np.flatnonzero(usable[: max(0, step)])
        held = poses[before[-1]] if len(before) else np.array(origin)  # logged_ego[k - 1] is the pose at step k
        out = np.empty((TRAJECTORY_POSES, 3))
        for i, index in enumerate(range(step, step + TRAJECTORY_POSES)):
            if 0 <= index < len(poses) and usable[index]:
                held = poses[index]
            out[i] = held
        local = poses_to_frame(out, origin)
        local[:, 2] = wrap_angle(local[:, 2])
        return local.astype(np.float32)
