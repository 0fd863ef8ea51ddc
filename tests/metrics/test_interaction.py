"""Distance to the nearest object between rounded boxes, and time to collision, on hand-built scenes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from langtraj.metrics.interaction import FAR, MAX_TTC, distance_to_nearest_object, time_to_collision

# 4 m x 2 m boxes: corners are rounded with radius 0.7 * 2 / 2 = 0.7, the core is 2.6 m x 0.6 m.
SHRINK = 0.7


def _boxes(*boxes, valid=None):
    """Arrays [1, A, 1] of x, y, heading, length, width, valid from (x, y, heading[, length, width]) tuples."""
    rows = [tuple(b) + (4.0, 2.0)[len(b) - 3 :] for b in boxes]
    cols = [np.array([[[r[i]] for r in rows]], np.float64) for i in range(5)]
    ok = np.ones((1, len(rows), 1), bool) if valid is None else np.array(valid, bool)[None, :, None]
    return (*cols, ok)


def _nearest(*boxes, evaluated=(0,), valid=None):
    return distance_to_nearest_object(*_boxes(*boxes, valid=valid), np.array(evaluated))[0, :, 0]


def test_face_to_face_gap_is_unchanged_by_rounding() -> None:
    # Centres 10 m apart along x: 10 - 2 - 2 = 6 m between the facing sides.
    np.testing.assert_allclose(_nearest((0, 0, 0), (10, 0, 0), evaluated=(0, 1)), [6.0, 6.0], atol=1e-12)
    # Side by side along y: 5 - 1 - 1 = 3 m.
    np.testing.assert_allclose(_nearest((0, 0, 0), (0, 5, 0)), [3.0], atol=1e-12)
    # Heading does not matter when both boxes turn together (here 90 degrees: long sides along y).
    np.testing.assert_allclose(_nearest((0, 0, math.pi / 2), (0, 10, math.pi / 2)), [6.0], atol=1e-9)


@pytest.mark.parametrize(("dx", "expected"), [(3.0, -1.0), (1.0, -2.0)])
def test_overlap_is_minus_penetration(dx: float, expected: float) -> None:
    # dx = 3: 1 m overlap along x. dx = 1: 3 m along x but only 2 m along y, the smaller depth.
    np.testing.assert_allclose(_nearest((0, 0, 0), (dx, 0, 0)), [expected], atol=1e-12)


@pytest.mark.parametrize("turn", [0.0, math.radians(30.0), math.radians(-100.0)])
def test_rotated_corner_to_corner(turn: float) -> None:
    # A at the origin, B turned 90 degrees, placed so the nearest core corners are (3, 4) apart:
    # A's core corner (1.3, 0.3) and B's core corner (-0.3, -1.3) from its centre (4.6, 5.6).
    # Rounded boxes: 5 - 2 * 0.7 = 3.6 (the sharp boxes would be sqrt(1.6^2 + 2.6^2) = 3.05 apart).
    # The whole configuration is then rotated by `turn`.
    c, s = math.cos(turn), math.sin(turn)
    bx, by = c * 4.6 - s * 5.6, s * 4.6 + c * 5.6
    got = _nearest((0, 0, turn), (bx, by, turn + math.pi / 2), evaluated=(0, 1))
    np.testing.assert_allclose(got, [5.0 - 2 * SHRINK] * 2, atol=1e-9)


def test_corner_rounding_of_unequal_boxes() -> None:
    # A 4 x 2 box and a 2 x 2 box (rounding 0.7, core 0.6 x 0.6), diagonal: cores' corners
    # (1.3, 0.3) and (x - 0.3, y - 0.3), 3 and 4 apart -> 5 - 0.7 - 0.7.
    got = _nearest((0, 0, 0), (1.3 + 3 + 0.3, 0.3 + 4 + 0.3, 0, 2.0, 2.0))
    np.testing.assert_allclose(got, [3.6], atol=1e-9)
    # A 6 x 3 box: rounding 1.05, core half sizes (1.95, 0.45).
    got = _nearest((0, 0, 0), (1.3 + 3 + 1.95, 0.3 + 4 + 0.45, 0, 6.0, 3.0))
    np.testing.assert_allclose(got, [5.0 - 0.7 - 1.05], atol=1e-9)


def test_self_excluded_and_lone_object_is_far() -> None:
    assert _nearest((0, 0, 0))[0] == FAR
    # Two objects at the same place still see each other (and not themselves).
    np.testing.assert_allclose(_nearest((0, 0, 0), (0, 0, 0), evaluated=(0, 1)), [-2.0, -2.0], atol=1e-12)


def test_invalid_partner_and_invalid_self_are_ignored() -> None:
    got = _nearest((0, 0, 0), (10, 0, 0), (30, 0, 0), valid=[True, False, True], evaluated=(0, 1))
    np.testing.assert_allclose(got[0], 30.0 - 4.0, atol=1e-12)  # the invalid box at 10 m does not count
    assert got[1] == FAR  # an invalid evaluated object gets FAR
    assert _nearest((0, 0, 0), (10, 0, 0), valid=[True, False])[0] == FAR


def test_nearest_among_several() -> None:
    boxes = [(0, 0, 0), (20, 0, 0), (0, -7, 0), (-9, 1, 0), (5, 6, math.pi / 2)]
    # Gaps from box 0: 16, 5, 5 (along x: 9 - 4; y offset 1 < 2 so faces overlap), and box 4 (4 x 2
    # turned upright at (5, 6)): its core spans x 4.7..5.3, y 4.7..7.3; box 0's core corner (1.3, 0.3)
    # -> gap (3.4, 4.4), so 5.5606 - 1.4 = 4.16, the nearest.
    corner = math.hypot(3.4, 4.4) - 2 * SHRINK
    np.testing.assert_allclose(_nearest(*boxes), [corner], atol=1e-9)
    # Box 1 (core x 18.7..21.3, y -0.3..0.3) is nearer box 4 (gap (13.4, 4.4)) than box 0 (16 m).
    got = _nearest(*boxes, evaluated=(0, 1, 2))
    np.testing.assert_allclose(got, [corner, math.hypot(13.4, 4.4) - 2 * SHRINK, 5.0], atol=1e-9)


def test_batched_over_rollouts_and_steps() -> None:
    # Object 1 moves away from object 0 along x by 1 m a step; rollout 1 is rollout 0 shifted by 2 m.
    n, t = 2, 4
    x = np.zeros((n, 2, t))
    x[:, 1] = 10 + np.arange(t) + 2 * np.arange(n)[:, None]
    zeros, ones = np.zeros_like(x), np.ones_like(x)
    got = distance_to_nearest_object(x, zeros, zeros, 4 * ones, 2 * ones, ones.astype(bool), np.array([0]))
    assert got.shape == (n, 1, t)
    np.testing.assert_allclose(got[:, 0], [[6, 7, 8, 9], [8, 9, 10, 11]], atol=1e-12)


def test_pruning_keeps_exact_minimum_on_random_scenes() -> None:
    """Many boxes at random: the pruned result equals the minimum over every pair computed alone."""
    rng = np.random.default_rng(3)
    a = 12
    x, y = rng.uniform(-15, 15, (2, 1, a, 1))
    heading = rng.uniform(-np.pi, np.pi, (1, a, 1))
    length, width = rng.uniform(3, 6, (1, a, 1)), rng.uniform(0.8, 2.5, (1, a, 1))
    valid = np.ones((1, a, 1), bool)
    pruned = distance_to_nearest_object(x, y, heading, length, width, valid, np.arange(a))[0, :, 0]
    for i in range(a):
        pair = [
            distance_to_nearest_object(*(v[:, [i, j]] for v in (x, y, heading, length, width, valid)), np.array([0]))
            for j in range(a)
            if j != i
        ]
        assert pruned[i] == pytest.approx(min(float(p[0, 0, 0]) for p in pair), abs=1e-12)


# ----------------------------------------------------------------------------------------------------------
# Time to collision.


def _ttc(*boxes, speeds, evaluated=(0,), valid=None):
    x, y, heading, length, width, ok = _boxes(*boxes, valid=valid)
    speed = np.array(speeds, np.float64)[None, :, None]
    return time_to_collision(x, y, heading, length, width, speed, ok, np.array(evaluated))[0, :, 0]


def test_ttc_follower_closing_on_leader() -> None:
    # Leader's back is 10 m ahead of the follower's front (14 - 2 - 2); closing at 10 - 5 m/s -> 2 s.
    np.testing.assert_allclose(_ttc((0, 0, 0), (14, 0, 0), speeds=[10.0, 5.0]), [2.0], atol=1e-12)
    # Same along a turned road.
    h = math.radians(140.0)
    leader = (14 * math.cos(h), 14 * math.sin(h), h)
    np.testing.assert_allclose(_ttc((0, 0, h), leader, speeds=[10.0, 5.0]), [2.0], atol=1e-9)
    # Far gaps are capped at 5 s: 40 m at 5 m/s would be 8 s.
    assert _ttc((0, 0, 0), (44, 0, 0), speeds=[10.0, 5.0])[0] == MAX_TTC


def test_ttc_nearest_leader_counts() -> None:
    # Leaders 10 m and 4 m ahead (gaps 14 - 4, 8 - 4); the nearer one (stopped) gives 4 / 10.
    got = _ttc((0, 0, 0), (14, 0, 0), (8, 0.5, 0), speeds=[10.0, 0.0, 0.0])
    np.testing.assert_allclose(got, [0.4], atol=1e-12)


def test_ttc_no_leader_or_not_closing() -> None:
    assert _ttc((0, 0, 0), speeds=[10.0])[0] == MAX_TTC
    assert _ttc((0, 0, 0), (14, 0, 0), speeds=[5.0, 10.0])[0] == MAX_TTC  # leader faster
    assert _ttc((0, 0, 0), (14, 0, 0), speeds=[5.0, 5.0])[0] == MAX_TTC  # same speed
    assert _ttc((0, 0, 0), (-14, 0, 0), speeds=[0.0, 10.0])[0] == MAX_TTC  # behind, not ahead
    assert _ttc((0, 0, 0), (14, 4, 0), speeds=[10.0, 0.0])[0] == MAX_TTC  # next lane: no lateral overlap
    assert _ttc((0, 0, 0), (14, 0, 0), speeds=[10.0, 0.0], valid=[True, False])[0] == MAX_TTC


def test_ttc_heading_limit() -> None:
    # 80 degrees off: not followed, even straight ahead.
    assert _ttc((0, 0, 0), (14, 0, math.radians(80.0)), speeds=[10.0, 0.0])[0] == MAX_TTC
    # 70 degrees off: followed; the leader's extent along the ego's axis is 2 cos 70 + 1 sin 70.
    yaw = math.radians(70.0)
    gap = 14 - 2 - (2 * math.cos(yaw) + 1 * math.sin(yaw))
    got = _ttc((0, 0, 0), (14, 0, yaw), speeds=[10.0, 0.0])
    np.testing.assert_allclose(got, [gap / 10.0], atol=1e-12)


def test_ttc_small_lateral_overlap_needs_close_alignment() -> None:
    # Lateral overlap 0.2 m (< 0.5 m): followed only within 10 degrees of heading.
    y = 2.0 - 0.2  # |y| - 1 - 1 = -0.2
    np.testing.assert_allclose(_ttc((0, 0, 0), (14, y, 0), speeds=[10.0, 5.0]), [2.0], atol=1e-12)
    yaw = math.radians(20.0)
    lat = 2 * math.sin(yaw) + 1 * math.cos(yaw)  # the leader's half extent across the ego's axis
    y = 1 + lat - 0.2
    assert _ttc((0, 0, 0), (14, y, yaw), speeds=[10.0, 5.0])[0] == MAX_TTC


def test_ttc_compares_headings_without_wrapping() -> None:
    # As in WOSAC: headings of pi - 0.05 and -pi + 0.05 differ by 0.1 rad on the road, but by
    # 2 pi - 0.1 as numbers, so the leader is not followed.
    h = math.pi - 0.05
    leader = (14 * math.cos(h), 14 * math.sin(h), -math.pi + 0.05)
    assert _ttc((0, 0, h), leader, speeds=[10.0, 5.0])[0] == MAX_TTC
    leader_same = (leader[0], leader[1], h)
    np.testing.assert_allclose(_ttc((0, 0, h), leader_same, speeds=[10.0, 5.0]), [2.0], atol=1e-9)


def test_ttc_nan_speed_gives_max() -> None:
    assert _ttc((0, 0, 0), (14, 0, 0), speeds=[np.nan, 5.0])[0] == MAX_TTC
