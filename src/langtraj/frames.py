"""Frame changes between world coordinates and a scene frame given as its origin pose (x, y, heading).

Samples, guidance geometry and simulation all express positions in the frame of a scene's focal agent;
these are the only conversions, so every module agrees on the convention.
"""

from __future__ import annotations

import math

import numpy as np

Origin = tuple[float, float, float]


def points_to_frame(xy: np.ndarray, origin: Origin) -> np.ndarray:
    """World points [..., 2] (or more columns; x, y first) in the frame, float64 [..., 2]."""
    ox, oy, oh = origin
    c, s = math.cos(oh), math.sin(oh)
    dx = np.asarray(xy, np.float64)[..., 0] - ox
    dy = np.asarray(xy, np.float64)[..., 1] - oy
    return np.stack([c * dx + s * dy, -s * dx + c * dy], axis=-1)


def poses_to_frame(poses: np.ndarray, origin: Origin) -> np.ndarray:
    """World poses [..., >= 3] (x, y, heading, then any columns, copied) in the frame (float64)."""
    out = np.array(poses, np.float64)
    out[..., :2] = points_to_frame(out, origin)
    out[..., 2] -= origin[2]
    return out


def poses_to_world(poses: np.ndarray, origin: Origin) -> np.ndarray:
    """Frame poses [..., >= 3] (x, y, heading, then any columns, copied) in world coordinates (float64)."""
    ox, oy, oh = origin
    c, s = math.cos(oh), math.sin(oh)
    out = np.array(poses, np.float64)
    out[..., 0] = ox + c * poses[..., 0] - s * poses[..., 1]
    out[..., 1] = oy + s * poses[..., 0] + c * poses[..., 1]
    out[..., 2] += oh
    return out
