"""Kinematic features by central differences: speed, acceleration, yaw rate and yaw acceleration.

As in WOSAC: derivatives are central differences over the whole track, so the first and last steps
(two steps for second derivatives) are NaN; heading differences are wrapped after doubling, which
picks the acute two-step change.

See docs/metrics.md.
"""

from __future__ import annotations

import numpy as np


def central_diff(values: np.ndarray) -> np.ndarray:
    """(v[t+1] - v[t-1]) / 2 along the last axis, NaN at both ends."""
    out = np.full(values.shape, np.nan, dtype=np.result_type(values, np.float32))
    out[..., 1:-1] = (values[..., 2:] - values[..., :-2]) / 2
    return out


def central_and(valid: np.ndarray) -> np.ndarray:
    """valid[t-1] & valid[t+1] along the last axis, False at both ends."""
    out = np.zeros(valid.shape, bool)
    out[..., 1:-1] = valid[..., 2:] & valid[..., :-2]
    return out


def _wrap(angle: np.ndarray) -> np.ndarray:
    # Not `angles.wrap_angle`: the official WOSAC code's [-pi, pi) in the input's dtype, to agree with it to 1e-7.
    return (angle + np.pi) % (2 * np.pi) - np.pi


def kinematic_features(
    x: np.ndarray, y: np.ndarray, z: np.ndarray, heading: np.ndarray, dt: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Linear speed (3-D), linear acceleration, angular speed and angular acceleration, each [..., T]."""
    dpos = np.stack([central_diff(x), central_diff(y), central_diff(z)])
    speed = np.sqrt((dpos**2).sum(axis=0)) / dt
    accel = central_diff(speed) / dt
    dh_step = _wrap(central_diff(heading) * 2) / 2
    d2h_step = _wrap(central_diff(dh_step) * 2) / 2
    return speed, accel, dh_step / dt, d2h_step / dt**2


def kinematic_validity(valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where speeds (both neighbours valid) and accelerations (speeds at both neighbours) are defined."""
    speed_valid = central_and(valid)
    return speed_valid, central_and(speed_valid)
