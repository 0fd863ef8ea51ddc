"""Polylines in the plane, in numpy: arc lengths, resampling, points at a station, and projections onto segments.

The one implementation of these for the map index (`roads`), behaviour targets (`interdrive.targets`)
and the road field (`guidance.road_field`); the differentiable torch projection is `guidance.geometry`'s. A
polyline is an array [N, 2] of (x, y) points (further columns, a z say, are ignored); a point's station is its arc
length along the polyline from the first point; a lateral offset is positive on the left of the direction of travel.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from langtraj.errors import InputError

DUPLICATE_M = 1e-6
"""Consecutive points at most this far apart are one point when resampling."""

_CHUNK_ELEMENTS = 1 << 22  # point x segment pairs per chunk of `project_on_polyline`'s search


def arc_lengths(points: np.ndarray) -> np.ndarray:
    """Station [N] of each point of a polyline [N, 2+] (0 at the first; empty for no points)."""
    if len(points) == 0:
        return np.zeros(0)
    steps = np.linalg.norm(np.diff(points[:, :2], axis=0), axis=1)
    return np.concatenate([[0.0], np.cumsum(steps)])


def resample(points: np.ndarray, spacing: float) -> np.ndarray:
    """A polyline [N, 2+] as [M, 2] points at equal steps of at most `spacing` along it, first and last kept,
    repeated points dropped; one point if it has no length, none if it has no points."""
    xy = points[:, :2]
    if len(xy) >= 2:
        keep = np.concatenate([[True], np.linalg.norm(np.diff(xy, axis=0), axis=1) > DUPLICATE_M])
        xy = xy[keep]
    if len(xy) < 2:
        return np.array(xy[:1], np.float64)
    s = arc_lengths(xy)
    num = max(1, math.ceil(s[-1] / spacing))
    s_new = np.linspace(0.0, s[-1], num + 1)
    return np.stack([np.interp(s_new, s, xy[:, 0]), np.interp(s_new, s, xy[:, 1])], axis=1)


def point_at(points: np.ndarray, station: float | np.ndarray) -> np.ndarray:
    """The point [..., 2] of a polyline [N >= 1, 2+] at each `station` [...] (clamped to its ends)."""
    if len(points) == 0:
        raise InputError("point_at: the polyline has no points")
    arc = arc_lengths(points)
    return np.stack([np.interp(station, arc, points[:, 0]), np.interp(station, arc, points[:, 1])], axis=-1)


class SegmentProjection(NamedTuple):
    """Points projected onto segments, one segment per point (arrays [...], `closest` [..., 2])."""

    t: np.ndarray  # where the closest point lies on its segment: 0 at the start, 1 at the end
    closest: np.ndarray  # the closest point of the segment
    distance: np.ndarray  # to the closest point
    offset: np.ndarray  # the distance, negative right of the segment (a point on its line counts as left)
    side: np.ndarray  # +1 left of the segment's line, -1 right of it, 0 on it
    station: np.ndarray  # the segment start's station plus t x the segment's length


def project_on_segments(
    points: np.ndarray, start: np.ndarray, end: np.ndarray, station: np.ndarray | float = 0.0
) -> SegmentProjection:
    """Each of `points` [..., 2] projected onto its segment start -> end [..., 2] (broadcasting), whose start lies
    at `station` [...] along its polyline; a zero-length segment projects everything onto its start."""
    direction = end - start
    relative = points - start
    length2 = (direction**2).sum(-1)
    t = np.clip((relative * direction).sum(-1) / np.maximum(length2, 1e-12), 0.0, 1.0)
    distance = np.linalg.norm(relative - t[..., None] * direction, axis=-1)
    side = np.sign(direction[..., 0] * relative[..., 1] - direction[..., 1] * relative[..., 0])
    return SegmentProjection(
        t=t,
        closest=start + t[..., None] * direction,
        distance=distance,
        offset=np.where(side >= 0, distance, -distance),
        side=side,
        station=station + t * np.sqrt(np.maximum(length2, 1e-12)),
    )


class PolylineProjection(NamedTuple):
    """Points projected onto the nearest segment of one polyline (arrays [...])."""

    station: np.ndarray  # of the closest point of the polyline
    offset: np.ndarray  # the distance to it, negative right of its segment (as `SegmentProjection.offset`)
    distance: np.ndarray  # to the polyline
    segment: np.ndarray  # int64, the nearest segment (k: from point k to k + 1; the first of equally near ones)


def project_on_polyline(points: np.ndarray, polyline: np.ndarray) -> PolylineProjection:
    """Each of `points` [..., 2] projected onto its nearest segment of `polyline` [N >= 1, 2+] (one point: a
    zero-length segment)."""
    line = np.asarray(polyline, np.float64)[:, :2]
    if len(line) == 0:
        raise InputError("project_on_polyline: the polyline has no points")
    if len(line) == 1:
        line = np.concatenate([line, line])
    start, end, arc = line[:-1], line[1:], arc_lengths(line)[:-1]
    flat = np.asarray(points, np.float64).reshape(-1, 2)
    segment = np.zeros(len(flat), np.int64)
    chunk = max(1, _CHUNK_ELEMENTS // len(start))
    for lo in range(0, len(flat), chunk):
        piece = flat[lo : lo + chunk]
        segment[lo : lo + chunk] = project_on_segments(piece[:, None], start, end).distance.argmin(-1)
    found = project_on_segments(flat, start[segment], end[segment], arc[segment])
    shape = np.shape(points)[:-1]
    return PolylineProjection(
        station=found.station.reshape(shape),
        offset=found.offset.reshape(shape),
        distance=found.distance.reshape(shape),
        segment=segment.reshape(shape),
    )


def ray_meets_polyline(
    origin: np.ndarray, heading: float, polyline: np.ndarray, first_m: float = 0.0, last_m: float = math.inf
) -> tuple[float, float] | None:
    """Where the ray from `origin` [2] along `heading` (rad) first meets `polyline` [P, 2] between `first_m` and
    `last_m` along it (first by the polyline's order): (the station there, the distance along the ray, m); None where
    it does not."""
    arc = arc_lengths(polyline)
    keep = np.flatnonzero((arc[1:] >= first_m) & (arc[:-1] <= last_m))
    if not keep.size:
        return None
    start, segment = polyline[keep], polyline[keep + 1] - polyline[keep]
    direction = np.array([math.cos(heading), math.sin(heading)])
    rel = start - np.asarray(origin, np.float64)
    denom = direction[0] * segment[:, 1] - direction[1] * segment[:, 0]
    parallel = np.abs(denom) < 1e-9
    denom = np.where(parallel, 1.0, denom)
    along = (rel[:, 0] * segment[:, 1] - rel[:, 1] * segment[:, 0]) / denom
    share = (rel[:, 0] * direction[1] - rel[:, 1] * direction[0]) / denom
    station = arc[keep] + share * (arc[keep + 1] - arc[keep])
    hit = ~parallel & (along > 0.0) & (share >= 0.0) & (share <= 1.0) & (station >= first_m) & (station <= last_m)
    if not hit.any():
        return None
    i = int(np.flatnonzero(hit)[0])
    return float(station[i]), float(along[i])
