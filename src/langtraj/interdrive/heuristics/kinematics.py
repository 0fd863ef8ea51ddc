"""`Kinematics`: each agent's speed, acceleration, course and yaw from its positions (gaps filled linearly, then
smoothed), as the heuristic labeler reads them (docs/interdrive.md, 'Single-agent labels')."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from langtraj.interdrive.heuristics.config import HeuristicConfig
from langtraj.scenario.model import Scenario


@dataclass(frozen=True, eq=False)
class Kinematics:
    """Motion of every agent over all steps, from positions: gaps filled linearly, then smoothed."""

    xy: np.ndarray  # float64 [A, T, 2], smoothed; meaningful where `span`
    span: np.ndarray  # bool [A, T], from the first to the last valid step of the agent
    speed: np.ndarray  # float64 [A, T]
    accel: np.ndarray  # float64 [A, T], derivative of the smoothed speed
    course: np.ndarray  # float64 [A, T], direction of motion
    yaw: np.ndarray  # float64 [A, T], box heading, unwrapped and gap-filled
    dt: float  # median step (s)

    @classmethod
    def compute(cls, scenario: Scenario, config: HeuristicConfig) -> Kinematics:
        """Kinematics of every agent of `scenario`."""
        agents = scenario.agents
        times = scenario.timestamps
        dt = float(np.median(np.diff(times))) if len(times) > 1 else 0.1
        xy, yaw, span = _fill_gaps(agents.xy.astype(np.float64), agents.heading.astype(np.float64), agents.valid)
        xy = _smooth(xy, span, _steps(config.position_smoothing_s, dt))
        step_dt = np.maximum(np.diff(times), 1e-6) if len(times) > 1 else np.ones(0)
        velocity = _derivative(xy, span, step_dt)
        speed = _smooth(np.linalg.norm(velocity, axis=-1), span, _steps(config.speed_smoothing_s, dt))
        accel = _smooth(_derivative(speed, span, step_dt), span, _steps(config.accel_smoothing_s, dt))
        course = np.arctan2(velocity[..., 1], velocity[..., 0])
        return cls(xy, span, speed, accel, course, _smooth(yaw, span, _steps(config.position_smoothing_s, dt)), dt)


def _steps(seconds: float, dt: float) -> int:
    return max(1, round(seconds / dt))


def _fill_gaps(xy: np.ndarray, yaw: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Positions and unwrapped yaw interpolated linearly across invalid steps inside each agent's valid span."""
    num_agents, num_steps = valid.shape
    span = np.zeros_like(valid)
    xy_out = np.zeros_like(xy)
    yaw_out = np.zeros_like(yaw)
    steps = np.arange(num_steps)
    for a in range(num_agents):
        idx = np.flatnonzero(valid[a])
        if len(idx) == 0:
            continue
        span[a, idx[0] : idx[-1] + 1] = True
        for c in range(2):
            xy_out[a, :, c] = np.interp(steps, idx, xy[a, idx, c])
        yaw_out[a] = np.interp(steps, idx, np.unwrap(yaw[a, idx]))
    return xy_out, yaw_out, span


def _smooth(values: np.ndarray, span: np.ndarray, window: int) -> np.ndarray:
    """Centred moving average over axis 1 inside each agent's (contiguous) span; the window shrinks
    symmetrically near the span's ends, so a linear motion is left unbiased there."""
    if window <= 1 or values.shape[1] == 0:
        return values
    num_steps = values.shape[1]
    steps = np.arange(num_steps)
    first = np.argmax(span, axis=1)[:, None]
    last = (num_steps - 1 - np.argmax(span[:, ::-1], axis=1))[:, None]
    half = np.clip(np.minimum(np.minimum(steps - first, last - steps), window // 2), 0, None)
    lo, hi = steps - half, steps + half + 1
    extra = (1,) * (values.ndim - 2)
    padded = np.concatenate([np.zeros_like(values[:, :1]), np.cumsum(values, axis=1)], axis=1)
    total = np.take_along_axis(padded, hi.reshape(hi.shape + extra), 1) - np.take_along_axis(
        padded, lo.reshape(lo.shape + extra), 1
    )
    smooth = total / (hi - lo).reshape(hi.shape + extra)
    return np.where(span.reshape(span.shape + extra), smooth, values)


def _derivative(values: np.ndarray, span: np.ndarray, step_dt: np.ndarray) -> np.ndarray:
    """Time derivative over axis 1: the mean of the differences on either side of each step inside `span`."""
    out = np.zeros_like(values)
    if values.shape[1] < 2:
        return out
    ok = (span[:, 1:] & span[:, :-1]).astype(np.float64)
    shape = ok.shape + (1,) * (values.ndim - 2)
    diff = np.diff(values, axis=1) / step_dt.reshape((1, -1) + (1,) * (values.ndim - 2)) * ok.reshape(shape)
    count = np.zeros(span.shape)
    out[:, 1:] += diff
    out[:, :-1] += diff
    count[:, 1:] += ok
    count[:, :-1] += ok
    return out / np.maximum(count, 1.0).reshape(count.shape + (1,) * (values.ndim - 2))
