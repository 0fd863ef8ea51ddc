"""`ConstantVelocity.model_states`: the constant-velocity rule's poses as the model's (x, y, heading, speed)."""

from __future__ import annotations

import numpy as np

from langtraj.rollouts.baselines import ConstantVelocity
from langtraj.scenario import StateField


def test_model_states_are_the_poses_with_the_first_steps_planar_speed():
    states = np.zeros((2, 4, 9))
    states[0, :, :3] = np.arange(4)[:, None] * (0.3, 0.4, 0.1)  # 0.5 m per step in the plane (z ignored)
    states[0, :, StateField.HEADING] = 0.7
    states[1, 2, StateField.VX : StateField.VY + 1] = (-6.0, 8.0)  # step 1 invalid: 10 m/s from the velocity
    states[1, :, StateField.HEADING] = -3.0
    valid = np.array([[True] * 4, [True, False, True, True]])
    rule = ConstantVelocity()
    out = rule.model_states(states, valid, 2, 5)
    poses = rule.poses(states, valid, 2, 5)
    assert out.shape == (2, 5, 4) and out.dtype == np.float64
    np.testing.assert_array_equal(out[..., :2], poses[..., :2])
    np.testing.assert_array_equal(out[..., 2], poses[..., 3])
    np.testing.assert_allclose(out[..., 2], [[0.7] * 5, [-3.0] * 5])
    np.testing.assert_allclose(out[..., 3], [[5.0] * 5, [10.0] * 5], rtol=1e-12)
    np.testing.assert_allclose(out[1, :, :2], [[-0.6 * k, 0.8 * k] for k in range(1, 6)], atol=1e-12)
