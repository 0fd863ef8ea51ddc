"""Interactive features: signed distance to the nearest object (collisions) and time to collision.

Objects are rectangles with rounded corners, as in WOSAC: each box is shrunk by
`0.7 * min(length, width) / 2` on every side to a "core" rectangle, and the distance between two
objects is the signed distance between their cores minus both shrink distances. Arrays are
[N, A, T] (N rollouts, A objects, T steps); results are [N, E, T] for the E evaluated objects.

See docs/metrics.md.
"""

from __future__ import annotations

import numpy as np

CORNER_ROUNDING = 0.7
"""0 gives sharp rectangles, 1 capsules; 0.7 fits most vehicle outlines (WOSAC's value)."""

FAR = 1e10
"""Distance given to pairs that do not count (self, invalid partner), so they never win a minimum."""

MAX_TTC = 5.0
"""Time to collision reported when no object is followed or the gap is not closing (seconds)."""

MAX_HEADING_DIFF = np.radians(75.0)
MAX_HEADING_DIFF_SMALL_OVERLAP = np.radians(10.0)
SMALL_OVERLAP = 0.5


def _rect_signed_distance(
    d: np.ndarray, ha: np.ndarray, ca: np.ndarray, sa: np.ndarray, hb: np.ndarray, cb: np.ndarray, sb: np.ndarray
) -> np.ndarray:
    """Signed distance between rectangles A and B (negative: penetration depth), for a batch of pairs.

    `d` [P, 2] is B's centre minus A's; `ha`, `hb` [P, 2] half length and half width; `ca, sa`,
    `cb, sb` [P] cosine and sine of the headings.
    """
    axes_a = np.stack([np.stack([ca, sa], -1), np.stack([-sa, ca], -1)], 1)  # [P, 2 axes, 2]
    axes_b = np.stack([np.stack([cb, sb], -1), np.stack([-sb, cb], -1)], 1)
    axes = np.concatenate([axes_a, axes_b], 1)  # [P, 4, 2]
    radius_a = np.abs(np.einsum("pkc,pjc->pkj", axes, axes_a)) @ ha[..., None]  # [P, 4, 1]
    radius_b = np.abs(np.einsum("pkc,pjc->pkj", axes, axes_b)) @ hb[..., None]
    separation = np.abs(np.einsum("pkc,pc->pk", axes, d)) - radius_a[..., 0] - radius_b[..., 0]
    max_sep = separation.max(axis=1)
    # Separated pairs: the nearest points are a corner of one box and the other box.
    corners = np.array([[1, 1], [-1, 1], [-1, -1], [1, -1]], np.float64)

    def corner_to_box(h_from, axes_from, offset, h_to, axes_to):
        local = corners[None] * h_from[:, None, :]  # corners in their own frame [P, 4, 2]
        world = np.einsum("pkj,pjc->pkc", local, axes_from) + offset[:, None, :]
        in_to = np.einsum("pkc,pjc->pkj", world, axes_to)  # in the other box's frame
        gap = np.maximum(np.abs(in_to) - h_to[:, None, :], 0.0)
        return np.sqrt((gap**2).sum(-1)).min(axis=1)

    outside = np.minimum(corner_to_box(ha, axes_a, -d, hb, axes_b), corner_to_box(hb, axes_b, d, ha, axes_a))
    return np.where(max_sep > 0, outside, max_sep)


def distance_to_nearest_object(
    x: np.ndarray,
    y: np.ndarray,
    heading: np.ndarray,
    length: np.ndarray,
    width: np.ndarray,
    valid: np.ndarray,
    evaluated: np.ndarray,
) -> np.ndarray:
    """Signed distance [N, E, T] from each evaluated object to the nearest other valid object.

    Inputs are [N, A, T]; `evaluated` indexes the object axis. Pairs that cannot be nearest (their
    lower bound exceeds another pair's upper bound) are skipped, which leaves every minimum exact.
    Where the evaluated object is invalid, or no other object is valid, the result is `FAR`.
    """
    shrink = np.minimum(length, width) * CORNER_ROUNDING / 2
    half = np.stack([length / 2 - shrink, width / 2 - shrink], -1)  # core half sizes [N, A, T, 2]
    circum = np.sqrt((half**2).sum(-1))
    ev = np.asarray(evaluated, np.int64)
    dx = x[:, None, :, :] - x[:, ev, None, :]  # [N, E, A, T]
    dy = y[:, None, :, :] - y[:, ev, None, :]
    centre = np.sqrt(dx**2 + dy**2)
    both = shrink[:, ev, None, :] + shrink[:, None, :, :]
    upper = centre - both
    lower = centre - circum[:, ev, None, :] - circum[:, None, :, :] - both
    usable = valid[:, ev, None, :] & valid[:, None, :, :]
    usable &= ev[None, :, None, None] != np.arange(x.shape[1])[None, None, :, None]
    upper = np.where(usable, upper, FAR)
    best_upper = upper.min(axis=2, keepdims=True)
    candidates = usable & (lower <= best_upper)
    n, e, a, t = np.nonzero(candidates)
    ia = ev[e]
    angle_a, angle_b = heading[n, ia, t], heading[n, a, t]
    exact = (
        _rect_signed_distance(
            np.stack([dx[n, e, a, t], dy[n, e, a, t]], -1),
            half[n, ia, t],
            np.cos(angle_a),
            np.sin(angle_a),
            half[n, a, t],
            np.cos(angle_b),
            np.sin(angle_b),
        )
        - both[n, e, a, t]
    )
    result = np.full(candidates.shape, FAR)
    result[n, e, a, t] = exact
    return result.min(axis=2)


def time_to_collision(
    x: np.ndarray,
    y: np.ndarray,
    heading: np.ndarray,
    length: np.ndarray,
    width: np.ndarray,
    speed: np.ndarray,
    valid: np.ndarray,
    evaluated: np.ndarray,
) -> np.ndarray:
    """Seconds until each evaluated object reaches the object it follows at constant speeds, [N, E, T].

    An object is followed when it is ahead of the ego's front, overlaps its straight trail laterally
    and is aligned within 75 degrees (10 degrees when the overlap is under 0.5 m); the nearest such
    object counts. Headings are compared without wrapping, as in WOSAC. No follower, a gap that is
    not closing or a NaN speed give `MAX_TTC`.
    """
    ev = np.asarray(evaluated, np.int64)
    ego_yaw = heading[:, ev, None, :]  # [N, E, 1, T]
    yaw_diff = np.abs(heading[:, None, :, :] - ego_yaw)  # [N, E, A, T]
    cos_d, sin_d = np.abs(np.cos(yaw_diff)), np.abs(np.sin(yaw_diff))
    half_l, half_w = length[:, None, :, :] / 2, width[:, None, :, :] / 2
    long_offset = half_l * cos_d + half_w * sin_d
    lat_offset = half_l * sin_d + half_w * cos_d
    dx = x[:, None, :, :] - x[:, ev, None, :]
    dy = y[:, None, :, :] - y[:, ev, None, :]
    c, s = np.cos(ego_yaw), np.sin(ego_yaw)
    rel_long = c * dx + s * dy
    rel_lat = -s * dx + c * dy
    long_distance = rel_long - length[:, ev, None, :] / 2 - long_offset
    lat_overlap = np.abs(rel_lat) - width[:, ev, None, :] / 2 - lat_offset
    following = (long_distance > 0) & (yaw_diff <= MAX_HEADING_DIFF) & (lat_overlap < 0)
    following &= (lat_overlap < -SMALL_OVERLAP) | (yaw_diff <= MAX_HEADING_DIFF_SMALL_OVERLAP)
    following &= valid[:, None, :, :]
    masked = np.where(following, long_distance, long_distance + FAR)
    ahead = masked.argmin(axis=2)  # [N, E, T]
    gap = np.take_along_axis(masked, ahead[:, :, None, :], axis=2)[:, :, 0, :]
    speed_b = np.broadcast_to(speed[:, None, :, :], masked.shape)
    ahead_speed = np.take_along_axis(speed_b, ahead[:, :, None, :], axis=2)[:, :, 0, :]
    closing = speed[:, ev, :] - ahead_speed
    with np.errstate(divide="ignore", invalid="ignore"):
        ttc = np.where(closing > 0, np.minimum(gap / closing, MAX_TTC), MAX_TTC)
    return ttc


def pair_signed_distance(
    x_a: np.ndarray,
    y_a: np.ndarray,
    heading_a: np.ndarray,
    length_a: np.ndarray,
    width_a: np.ndarray,
    x_b: np.ndarray,
    y_b: np.ndarray,
    heading_b: np.ndarray,
    length_b: np.ndarray,
    width_b: np.ndarray,
) -> np.ndarray:
    """Signed distance between the rounded boxes of objects A and B (negative: they overlap), elementwise.

    The inputs broadcast to one shape (e.g. [R, T] poses with scalar sizes), which the result has. The
    rule is that of `distance_to_nearest_object`, for one given pair instead of the nearest of all.
    """
    values = (x_a, y_a, heading_a, length_a, width_a, x_b, y_b, heading_b, length_b, width_b)
    args = np.broadcast_arrays(*(np.asarray(v, np.float64) for v in values))
    shape = args[0].shape
    xa, ya, ha, la, wa, xb, yb, hb, lb, wb = (a.reshape(-1) for a in args)
    shrink_a = np.minimum(la, wa) * CORNER_ROUNDING / 2
    shrink_b = np.minimum(lb, wb) * CORNER_ROUNDING / 2
    half_a = np.stack([la / 2 - shrink_a, wa / 2 - shrink_a], -1)
    half_b = np.stack([lb / 2 - shrink_b, wb / 2 - shrink_b], -1)
    d = np.stack([xb - xa, yb - ya], -1)
    core = _rect_signed_distance(d, half_a, np.cos(ha), np.sin(ha), half_b, np.cos(hb), np.sin(hb))
    return (core - shrink_a - shrink_b).reshape(shape)
