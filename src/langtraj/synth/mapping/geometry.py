"""Polyline geometry of the SUMO net -> map conversion: resampling, offsetting, splitting rings.
See docs/data.md.
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from langtraj.synth.mapping.common import _MIN_STEP_M

# ---------------------------------------------------------------------------------------------- geometry


def _dedupe(points: np.ndarray) -> np.ndarray:
    """Points without consecutive duplicates."""
    if len(points) < 2:
        return points
    step = np.linalg.norm(np.diff(points[:, :2], axis=0), axis=1)
    return points[np.concatenate([[True], step > _MIN_STEP_M])]


def densify(points: np.ndarray, spacing: float | None) -> np.ndarray:
    """The polyline with points inserted evenly so that no segment is longer than `spacing` (None: as is)."""
    if spacing is None or len(points) < 2:
        return points
    seg = np.diff(points, axis=0)
    length = np.linalg.norm(seg[:, :2], axis=1)
    parts = np.maximum(1, np.ceil(length / spacing - 1e-9)).astype(np.int64)
    start = np.repeat(points[:-1], parts, axis=0)
    frac = np.arange(parts.sum()) - np.repeat(np.cumsum(parts) - parts, parts)
    frac = (frac / np.repeat(parts, parts))[:, None]
    return np.concatenate([start + frac * np.repeat(seg, parts, axis=0), points[-1:]])


def offset_polyline(points: np.ndarray, distance: float) -> np.ndarray:
    """The polyline moved `distance` to its left (negative: right), with mitred vertices; same point count."""
    xy = points[:, :2]
    seg = np.diff(xy, axis=0)
    tangent = seg / np.maximum(np.linalg.norm(seg, axis=1, keepdims=True), _MIN_STEP_M)
    normal = np.stack([-tangent[:, 1], tangent[:, 0]], axis=1)
    before = np.concatenate([normal[:1], normal])
    after = np.concatenate([normal, normal[-1:]])
    cos_full = np.maximum(np.sum(before * after, axis=1, keepdims=True), -0.8)
    mitre = (before + after) / (1.0 + cos_full)
    out = points.copy()
    out[:, :2] = xy + distance * mitre
    return out


def _right_normal_at_end(points: np.ndarray) -> np.ndarray:
    d = points[-1, :2] - points[-2, :2]
    d = d / max(float(np.linalg.norm(d)), _MIN_STEP_M)
    return np.array([d[1], -d[0]])


def _split_ring(ring: np.ndarray, max_length: float) -> list[np.ndarray]:
    """A closed ring as consecutive pieces no longer than about `max_length`, sharing end points."""
    cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(ring[:, :2], axis=0), axis=1))])
    pieces = max(1, math.ceil(cum[-1] / max_length))
    if pieces == 1 or len(ring) < 2 * pieces + 1:
        return [ring]
    cuts = np.searchsorted(cum, cum[-1] * np.arange(1, pieces) / pieces)
    bounds = np.unique(np.concatenate([[0], np.clip(cuts, 1, len(ring) - 2), [len(ring) - 1]]))
    return [ring[a : b + 1] for a, b in itertools.pairwise(bounds)]
