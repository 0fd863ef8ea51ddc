"""Central-difference kinematics: speeds, accelerations, yaw rates and their validity, by hand."""

from __future__ import annotations

import numpy as np
import pytest

from langtraj.metrics.kinematics import central_and, central_diff, kinematic_features, kinematic_validity

DT = 0.1


def test_central_diff_by_hand() -> None:
    out = central_diff(np.array([0.0, 1.0, 4.0, 9.0, 16.0]))
    assert np.isnan(out[0]) and np.isnan(out[-1])
    np.testing.assert_array_equal(out[1:-1], [2.0, 4.0, 6.0])  # (4-0)/2, (9-1)/2, (16-4)/2


def test_constant_acceleration_straight_track() -> None:
    a, num = 2.0, 12
    t = np.arange(num) * DT
    x = 0.5 * a * t**2
    zeros = np.zeros(num)
    speed, accel, yaw_rate, yaw_accel = kinematic_features(x, zeros, zeros, zeros, DT)
    # v(t) = (x(t + dt) - x(t - dt)) / (2 dt) = a t exactly for a parabola.
    assert np.isnan(speed[[0, -1]]).all()
    np.testing.assert_allclose(speed[1:-1], a * t[1:-1], rtol=1e-12, atol=1e-12)
    assert np.isnan(accel[[0, 1, -2, -1]]).all()
    np.testing.assert_allclose(accel[2:-2], a, rtol=1e-9)
    np.testing.assert_allclose(yaw_rate[1:-1], 0.0)
    np.testing.assert_allclose(yaw_accel[2:-2], 0.0)


def test_speed_is_three_dimensional() -> None:
    t = np.arange(5.0)
    speed = kinematic_features(3.0 * t, np.zeros(5), 4.0 * t, np.zeros(5), DT)[0]
    np.testing.assert_allclose(speed[1:-1], 5.0 / DT)  # |(3, 0, 4)| per step


@pytest.mark.parametrize("omega", [0.6, -0.6])
def test_constant_yaw_rate_across_the_wrap(omega: float) -> None:
    num = 40
    raw = 3.0 * np.sign(omega) + omega * DT * np.arange(num)  # passes +-pi around step 2
    heading = (raw + np.pi) % (2 * np.pi) - np.pi
    assert np.abs(np.diff(heading)).max() > np.pi  # the track does cross the wrap
    zeros = np.zeros(num)
    _, _, yaw_rate, yaw_accel = kinematic_features(zeros, zeros, zeros, heading, DT)
    assert np.isnan(yaw_rate[[0, -1]]).all() and np.isnan(yaw_accel[[0, 1, -2, -1]]).all()
    np.testing.assert_allclose(yaw_rate[1:-1], omega, rtol=1e-9)
    np.testing.assert_allclose(yaw_accel[2:-2], 0.0, atol=1e-9)


def test_batched_shapes() -> None:
    x = np.broadcast_to(np.arange(6.0), (2, 3, 6))
    outs = kinematic_features(x, np.zeros_like(x), np.zeros_like(x), np.zeros_like(x), DT)
    assert all(o.shape == (2, 3, 6) for o in outs)
    np.testing.assert_allclose(outs[0][..., 1:-1], 10.0)


def test_validity_masks() -> None:
    valid = np.array([True, True, True, False, True, True, True, True])
    assert central_and(valid).tolist() == [False, True, False, True, False, True, True, False]
    speed_valid, accel_valid = kinematic_validity(valid)
    assert speed_valid.tolist() == [False, True, False, True, False, True, True, False]
    # Only the neighbours count (step 3 itself is invalid, its speed is still defined), and an
    # acceleration needs speeds at t - 1 and t + 1.
    assert accel_valid.tolist() == [False, False, True, False, True, False, False, False]
    assert not central_and(np.ones(2, bool)).any()
    both = kinematic_validity(np.ones((2, 5), bool))
    assert both[0].tolist() == [[False, True, True, True, False]] * 2
    assert both[1].tolist() == [[False, False, True, False, False]] * 2
