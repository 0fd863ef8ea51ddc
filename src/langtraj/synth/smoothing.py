"""Repairs for what SUMO gets wrong at 10 Hz, applied to every synthesized track.

- Vehicles: in the sublane model a vehicle that stops in the middle of a lane change keeps moving
  sideways, and SUMO turns its angle towards that sideways motion (up to 90 degrees at standstill).
  A car cannot yaw faster than its speed times its largest curvature, so the heading is rate-limited
  to `speed * MAX_CURVATURE` (plus a small allowance); a stopped car keeps its heading.
- Pedestrians: the striping model moves people between stripes and walking-area paths in jumps, and
  their angle flips with them. Jumps beyond a walking speed are replaced by a linear interpolation,
  positions are averaged over a short centred window, and the heading follows the smoothed motion
  (held while standing).

See docs/data.md.
"""

from __future__ import annotations

import math

import numpy as np

from langtraj.angles import wrap_angle
from langtraj.scenario.model import STEP_SECONDS

MAX_CURVATURE = 0.25
"""1/m: tightest turn of a car (4 m radius), bounds the yaw rate at a given speed."""

YAW_ALLOWANCE = 0.02
"""rad per step a heading may change whatever the speed (keeps slow manoeuvres possible)."""

PEDESTRIAN_MAX_STEP = 0.45
"""m per 0.1 s step (4.5 m/s): a larger pedestrian displacement is a model jump, not walking."""

PEDESTRIAN_WINDOW = 7
"""Steps in the centred moving average of pedestrian positions."""

STANDING_SPEED = 0.2
"""m/s below which a pedestrian's heading is held."""


def limit_yaw_rate(heading: np.ndarray, speed: np.ndarray) -> np.ndarray:
    """Headings whose step-to-step change is at most `speed * MAX_CURVATURE * dt + YAW_ALLOWANCE`."""
    if heading.size == 0:
        return np.zeros(0, np.float64)
    limits = (np.maximum(speed[1:], speed[:-1]) * MAX_CURVATURE * STEP_SECONDS + YAW_ALLOWANCE).tolist()
    raw = np.asarray(heading, np.float64).tolist()
    out = [raw[0]]
    for target, limit in zip(raw[1:], limits, strict=True):  # sequential: each step follows the last output
        delta = math.remainder(target - out[-1], 2 * math.pi)
        out.append(out[-1] + min(max(delta, -limit), limit))
    return wrap_angle(np.array(out))


def remove_jumps(xy: np.ndarray, max_step: float = PEDESTRIAN_MAX_STEP) -> np.ndarray:
    """Positions where each step longer than `max_step` is replaced by interpolating across it.

    The points after a jump are shifted back by the jump vector fading out linearly over the second
    following the jump, so the track ends where SUMO's does and has no discontinuity.
    """
    xy = np.array(xy, np.float64)
    n = len(xy)
    if n < 2:
        return xy
    steps = np.diff(xy, axis=0)
    for i in np.flatnonzero(np.linalg.norm(steps, axis=1) > max_step):
        jump = steps[i] - (steps[i - 1] if i > 0 else 0.0)  # keep the walking motion of the step
        span = min(10, n - 2 - i)
        fade = np.linspace(1.0, 0.0, span + 1)[:, None]
        xy[i + 1 : i + 2 + span] -= jump * fade
    return xy


def moving_average(xy: np.ndarray, window: int = PEDESTRIAN_WINDOW) -> np.ndarray:
    """Centred moving average with the window shrunk at both ends (endpoints are kept)."""
    n = len(xy)
    if n < 3 or window < 2:
        return np.array(xy, np.float64)
    half = window // 2
    csum = np.concatenate([np.zeros((1, xy.shape[1])), np.cumsum(xy, axis=0)])
    idx = np.arange(n)
    reach = np.minimum(np.minimum(idx, n - 1 - idx), half)
    return (csum[idx + reach + 1] - csum[idx - reach]) / (2 * reach + 1)[:, None]


def heading_from_motion(xy: np.ndarray, fallback: np.ndarray, min_speed: float = STANDING_SPEED) -> np.ndarray:
    """Heading of the (central-difference) velocity; held while slower than `min_speed`.

    Before the first move the first moving heading is used, or `fallback` if the agent never moves.
    """
    n = len(xy)
    if n < 2:
        return np.array(fallback, np.float64)
    vel = np.gradient(xy, STEP_SECONDS, axis=0)
    moving = np.linalg.norm(vel, axis=1) >= min_speed
    if not moving.any():
        return np.array(fallback, np.float64)
    raw = np.arctan2(vel[:, 1], vel[:, 0])
    last = np.maximum.accumulate(np.where(moving, np.arange(n), -1))
    first = int(np.argmax(moving))
    return raw[np.where(last >= 0, last, first)]


def smooth_pedestrian(xy: np.ndarray, sumo_heading: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pedestrian positions without model jumps, lightly averaged, and headings that follow them."""
    smoothed = moving_average(remove_jumps(xy))
    return smoothed, heading_from_motion(smoothed, sumo_heading)
