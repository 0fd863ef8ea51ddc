"""Red-light violations: an object on a lane whose signal is red crosses that signal's stop point.

This follows the WOSAC definition step for step, including how it picks "the lane the object is on":
the official code ranks lane segments by |p - s + (e - s) * t| (t the clipped projection), not by
the distance from p to the segment; `exact_lane_match=True` uses the true distance instead. The
default reproduces the challenge's figures (docs/metrics.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from langtraj.scenario.model import Scenario
from langtraj.scenario.types import RED_STATES, MapFeatureType


@dataclass(frozen=True)
class SignalLanes:
    """Surface-street lanes as padded polylines, and the scene's signal states per step."""

    lane_ids: np.ndarray  # int64 [L]
    points: np.ndarray  # float64 [L, P, 2], padded
    point_valid: np.ndarray  # bool [L, P]
    signal_lane: np.ndarray  # int64 [S], lane id of each signal
    signal_is_stop: np.ndarray  # bool [T, S]
    stop_points: np.ndarray  # float64 [S, 2]

    @classmethod
    def from_scenario(cls, scenario: Scenario) -> SignalLanes | None:
        """The scene's signalled lanes, or None when it has no surface-street lane or no signal."""
        lanes = [f for f in scenario.road_map if f.type == MapFeatureType.LANE_SURFACE_STREET and len(f.points) >= 2]
        lights = scenario.traffic_lights
        if not lanes or lights.num_lanes == 0:
            return None
        longest = max(len(f.points) for f in lanes)
        points = np.zeros((len(lanes), longest, 2))
        point_valid = np.zeros((len(lanes), longest), bool)
        for i, feature in enumerate(lanes):
            points[i, : len(feature.points)] = feature.points[:, :2]
            point_valid[i, : len(feature.points)] = True
        is_stop = np.isin(lights.states, [int(s) for s in RED_STATES]) & lights.valid
        return cls(
            np.array([f.id for f in lanes], np.int64),
            points,
            point_valid,
            lights.lane_ids.astype(np.int64),
            is_stop,
            lights.stop_points[:, :2].astype(np.float64),
        )


def _nearest_segment(xy: np.ndarray, points: np.ndarray, point_valid: np.ndarray, exact: bool):
    """(lane, segment) of the nearest lane segment for query points [M, 2] over lanes [L, P, 2]."""
    start, end = points[:, :-1], points[:, 1:]
    along = end - start  # [L, S, 2]
    seg_valid = point_valid[:, :-1]  # as the official code: the start point's flag
    num_seg = seg_valid.shape[1]
    lane = np.zeros(len(xy), np.int64)
    seg = np.zeros(len(xy), np.int64)
    for chunk in np.array_split(np.arange(len(xy)), max(1, len(xy) // 64)):
        to_point = xy[chunk, None, None, :] - start[None]
        denom = (along**2).sum(-1)[None]
        with np.errstate(divide="ignore", invalid="ignore"):
            rel = np.where(denom > 0, (to_point * along[None]).sum(-1) / denom, 0.0)
        step = along[None] * np.clip(rel, 0.0, 1.0)[..., None]
        offset = to_point - step if exact else to_point + step
        dist = np.where(seg_valid[None], np.sqrt((offset**2).sum(-1)), 1e10)
        flat = dist.reshape(len(chunk), -1).argmin(axis=1)
        lane[chunk], seg[chunk] = flat // num_seg, flat % num_seg
    return lane, seg


def red_light_violations(
    signals: SignalLanes | None, x: np.ndarray, y: np.ndarray, valid: np.ndarray, *, exact_lane_match: bool = False
) -> np.ndarray:
    """Violation flags [..., T] for tracks x, y, valid [..., T] over the scene's T steps.

    A step counts when the object is valid, its current lane has a signal in a stop state at that
    step, and it passed the signal's stop point between the previous step and this one.
    """
    shape = x.shape
    violation = np.zeros(shape, bool)
    if signals is None:
        return violation
    num_steps = shape[-1]
    lane_pos = {int(lid): i for i, lid in enumerate(signals.lane_ids)}
    # Crossings of red stop points first; the (costly) current lane is looked up only where one happens.
    crossings: list[tuple[np.ndarray, int]] = []
    for k, sig_lane in enumerate(signals.signal_lane):
        if int(sig_lane) not in lane_pos or not signals.signal_is_stop[:num_steps, k].any():
            continue
        li = lane_pos[int(sig_lane)]
        stop = signals.stop_points[k]
        lane_points, lane_valid = signals.points[li : li + 1], signals.point_valid[li : li + 1]
        _, seg = _nearest_segment(stop[None], lane_points, lane_valid, exact_lane_match)
        s, e = signals.points[li, seg[0]], signals.points[li, seg[0] + 1]
        along = e - s
        length2 = float(along @ along)
        if length2 == 0:
            continue
        stop_t = float((stop - s) @ along) / length2
        obj_t = ((np.stack([x, y], -1) - s) @ along) / length2  # [..., T]
        crossed = np.zeros(shape, bool)
        crossed[..., 1:] = (obj_t[..., :-1] < stop_t) & (obj_t[..., 1:] > stop_t)
        hit = valid & crossed & signals.signal_is_stop[:num_steps, k]
        if hit.any():
            crossings.append((hit, int(sig_lane)))
    if not crossings:
        return violation
    where = np.logical_or.reduce([hit for hit, _ in crossings])
    xy = np.stack([x[where], y[where]], -1).astype(np.float64)
    lane_idx, _ = _nearest_segment(xy, signals.points, signals.point_valid, exact_lane_match)
    current_lane = np.full(shape, -1, np.int64)
    current_lane[where] = signals.lane_ids[lane_idx]
    for hit, sig_lane in crossings:
        violation |= hit & (current_lane == sig_lane)
    return violation
