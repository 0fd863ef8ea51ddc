"""`checked_action`, the one check of a planner's action: shape, finiteness and, for a trajectory, the space's
bounds on positions (headings wrapped, not refused)."""

from __future__ import annotations

import numpy as np
import pytest

from langtraj.env.spaces import TRAJECTORY_BOUND_M, TRAJECTORY_POSES, ActionError, action_space, checked_action


def _trajectory(**at: tuple[float, float, float]) -> np.ndarray:
    poses = np.stack(
        [0.5 * np.arange(1, TRAJECTORY_POSES + 1), np.zeros(TRAJECTORY_POSES), np.zeros(TRAJECTORY_POSES)], 1
    )
    for k, pose in at.items():
        poses[int(k[1:])] = pose
    return poses


def test_a_trajectory_in_the_space_passes_with_its_headings_wrapped():
    values = checked_action(_trajectory(p3=(2.0, 0.1, 3 * np.pi / 2)), "trajectory")
    assert values.shape == action_space("trajectory").shape
    assert values[3, 2] == pytest.approx(-np.pi / 2) and values[0, 0] == 0.5
    assert action_space("trajectory").contains(values.astype(np.float32))


def test_a_pose_beyond_the_space_is_one_error_naming_it():
    with pytest.raises(ActionError) as raised:
        checked_action(_trajectory(p4=(500.0, 0.0, 0.0)), "trajectory")
    assert str(raised.value) == f"a trajectory pose 4 500.0 m from the ego, beyond the space's {TRAJECTORY_BOUND_M:g} m"


@pytest.mark.parametrize(
    ("action", "message"),
    [
        ([1.0], "an action of shape (1,), expected (2,)"),
        ([np.nan, 0.0], "a non-finite action"),
        ("fast", "not an array of numbers"),
    ],
)
def test_bad_controls_are_refused(action, message):
    with pytest.raises(ActionError, match=message.replace("(", r"\(").replace(")", r"\)")):
        checked_action(action, "control")
    assert checked_action([20.0, 0.0], "control")[0] == 20.0  # a control is clipped by the env, not refused here
