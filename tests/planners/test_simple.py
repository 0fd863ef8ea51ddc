"""Constant velocity and log replay: actions, frames, the log's gaps and end."""

from __future__ import annotations

import math

import numpy as np
import pytest

from langtraj.env.spaces import TRAJECTORY_POSES, action_space
from langtraj.errors import InputError
from langtraj.planners import ConstantVelocityPlanner, LogReplayPlanner

from .helpers import make_observation


def test_constant_velocity_keeps_speed_and_heading():
    action = ConstantVelocityPlanner().act(make_observation())
    assert action.dtype == np.float32 and action_space("control").contains(action)
    np.testing.assert_array_equal(action, [0.0, 0.0])


def _logged(heading: float = math.pi / 2, speed: float = 5.0, start=(100.0, 200.0)) -> np.ndarray:
    """A straight logged drive from `start` along `heading`: [80, 4] world poses at steps 1 .. 80."""
    s = speed * 0.1 * np.arange(1, 81)
    x, y = start[0] + s * math.cos(heading), start[1] + s * math.sin(heading)
    return np.stack([x, y, np.full(80, heading), np.full(80, speed)], axis=1)


def test_log_replay_gives_the_logged_path_in_the_ego_frame():
    logged = _logged()
    planner = LogReplayPlanner()
    assert planner.action_kind == "trajectory"
    planner.reset(make_observation(pose=(100.0, 200.0, math.pi / 2)), {"logged_ego": logged, "step_seconds": 0.1})
    # at step 3 the ego is where the log has it (logged_ego[2]): the next poses lie straight ahead every 0.5 m
    obs = make_observation(pose=tuple(logged[2, :3]), time=0.3)
    trajectory = planner.act(obs)
    assert trajectory.shape == (TRAJECTORY_POSES, 3) and trajectory.dtype == np.float32
    expected = np.stack([0.5 * np.arange(1, 11), np.zeros(10), np.zeros(10)], axis=1)
    np.testing.assert_allclose(trajectory, expected, atol=1e-4)
    # an ego 1 m right of the log sees it 1 m to its left
    shifted = make_observation(pose=(logged[2, 0] + 1.0, logged[2, 1], math.pi / 2), time=0.3)
    np.testing.assert_allclose(planner.act(shifted)[:, 1], 1.0, atol=1e-4)


def test_log_replay_holds_the_last_valid_pose_through_gaps_and_past_the_end():
    logged = _logged()
    logged[5:8] = np.nan
    planner = LogReplayPlanner()
    planner.reset(make_observation(), {"logged_ego": logged})
    gap = planner.act(make_observation(pose=tuple(logged[2, :3]), time=0.3))
    assert np.isfinite(gap).all()
    np.testing.assert_allclose(gap[2:5], np.repeat(gap[1:2], 3, axis=0))  # steps 6..8 hold step 5's pose
    near_end = planner.act(make_observation(pose=tuple(logged[75, :3]), time=7.6))
    assert np.isfinite(near_end).all()
    np.testing.assert_allclose(near_end[4:], np.repeat(near_end[3:4], 6, axis=0))  # the log ends at step 80
    past = planner.act(make_observation(pose=tuple(logged[79, :3]), time=9.0))
    np.testing.assert_allclose(past, np.zeros((10, 3)), atol=1e-4)  # hold the log's last pose, where the ego is


def test_log_replay_without_a_logged_state_holds_the_current_pose():
    planner = LogReplayPlanner()
    planner.reset(make_observation(), {"logged_ego": np.full((80, 4), np.nan)})
    np.testing.assert_array_equal(planner.act(make_observation(pose=(3.0, 4.0, 1.0), time=1.0)), np.zeros((10, 3)))


def test_log_replay_refuses_a_reset_info_without_the_log():
    with pytest.raises(InputError, match="logged_ego"):
        LogReplayPlanner().reset(make_observation(), {})
