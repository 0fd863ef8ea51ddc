"""Signed distance to the road edge: sides, corners, overpasses, loops, and the exact k-d tree search."""

from __future__ import annotations

import math

import numpy as np
import pytest

from langtraj.metrics.road import FAR, Z_STRETCH, RoadEdgeIndex, RoadEdges, distance_to_road_edge

STRAIGHT = [np.array([[-50.0, 0, 0], [50.0, 0, 0]])]  # along +x: the road is y > 0


def _index(polylines) -> RoadEdgeIndex:
    return RoadEdgeIndex(RoadEdges.from_polylines([np.asarray(p, np.float64) for p in polylines]))


def _box_distance(index, x, y, heading=0.0, length=4.0, width=2.0, z=0.75, height=1.5, valid=True):
    args = [np.atleast_1d(np.asarray(v, np.float64)) for v in (x, y, z, heading, length, width, height)]
    return distance_to_road_edge(index, *args, np.atleast_1d(np.asarray(valid)))


def _signed(index, *points) -> np.ndarray:
    return index.signed_distance(np.array(points, np.float64))


def test_box_on_crossing_and_off_the_road() -> None:
    index = _index(STRAIGHT)
    # Corners at y = 4 and 6: the most off-road corner is 4 m inside.
    np.testing.assert_allclose(_box_distance(index, 0.0, 5.0), [-4.0], atol=1e-12)
    # Corners at y = 1.5 and -0.5: half a metre off.
    np.testing.assert_allclose(_box_distance(index, 0.0, 0.5), [0.5], atol=1e-12)
    # Fully off: corners at y = -4 and -6.
    np.testing.assert_allclose(_box_distance(index, 0.0, -5.0), [6.0], atol=1e-12)
    # Turned 90 degrees: corners at y = 3 and 7.
    np.testing.assert_allclose(_box_distance(index, 10.0, 5.0, heading=math.pi / 2), [-3.0], atol=1e-9)
    # Turned 45 degrees: the lowest corner is sqrt(2^2 + 1^2) * sin(45 deg + atan(1 / 2)) below the centre.
    drop = math.hypot(2.0, 1.0) * math.sin(math.radians(45.0) + math.atan(0.5))
    np.testing.assert_allclose(_box_distance(index, 0.0, 5.0, heading=math.pi / 4), [-(5.0 - drop)], atol=1e-9)


def test_reversed_edge_flips_the_side() -> None:
    index = _index([STRAIGHT[0][::-1]])  # along -x: the road is y < 0
    np.testing.assert_allclose(_box_distance(index, 0.0, 5.0), [6.0], atol=1e-12)
    np.testing.assert_allclose(_box_distance(index, 0.0, -5.0), [-4.0], atol=1e-12)


def test_invalid_is_minus_far() -> None:
    index = _index(STRAIGHT)
    got = _box_distance(index, [0.0, 0.0], [5.0, -5.0], valid=[False, True])
    assert got[0] == -FAR == -1e10
    assert got[1] == pytest.approx(6.0)


def test_right_angle_corners() -> None:
    # Left turn (0,0) -> (10,0) -> (10,10): the road is the quadrant x < 10, y > 0 (a convex corner).
    left = _index([[[0, 0, 0], [10, 0, 0], [10, 10, 0]]])
    np.testing.assert_allclose(_signed(left, (9, 1, 0), (12, -2, 0), (12, 5, 0)), [-1, math.sqrt(8), 2], atol=1e-12)
    # Right turn (0,0) -> (10,0) -> (10,-10): the road is everything but the quadrant x < 10, y < 0.
    right = _index([[[0, 0, 0], [10, 0, 0], [10, -10, 0]]])
    np.testing.assert_allclose(_signed(right, (8, -2, 0), (12, 2, 0), (12, -5, 0)), [2, -math.sqrt(8), -2], atol=1e-12)


def test_sharp_convex_corner_takes_the_off_road_side() -> None:
    # Left turn by 135 degrees: (0,0) -> (10,0) -> (0,10). The road is the wedge between them. The
    # point (12, 1) is nearest the joint (10, 0) (a tie between both segments); it is left of the
    # first segment but right of the second, so off the road: +sqrt(5).
    index = _index([[[0, 0, 0], [10, 0, 0], [0, 10, 0]]])
    np.testing.assert_allclose(_signed(index, (12, 1, 0)), [math.sqrt(5)], atol=1e-12)
    # Inside the wedge near the joint: nearest the second segment (the line x + y = 10).
    np.testing.assert_allclose(_signed(index, (8, 1, 0)), [-1 / math.sqrt(2)], atol=1e-12)


def test_sharp_concave_corner_takes_the_road_side() -> None:
    # Right turn by 135 degrees: (0,0) -> (10,0) -> (0,-10). The road is left of either segment. The
    # point (12, -1) is right of the first segment but left of the second: on the road, -sqrt(5).
    index = _index([[[0, 0, 0], [10, 0, 0], [0, -10, 0]]])
    np.testing.assert_allclose(_signed(index, (12, -1, 0)), [-math.sqrt(5)], atol=1e-12)
    # Between the segments, right of both (the second lies on x - y = 10): off the road.
    np.testing.assert_allclose(_signed(index, (8, -1, 0)), [1 / math.sqrt(2)], atol=1e-12)


def test_open_end_keeps_its_own_side() -> None:
    index = _index(STRAIGHT)
    np.testing.assert_allclose(_signed(index, (53, 4, 0), (53, -4, 0)), [-5, 5], atol=1e-12)


def test_overpass_is_not_chosen_over_a_lower_edge() -> None:
    # An edge 10 m up, 1 m away in plan, against a ground edge 15 m away in plan. Plain 3-D distance
    # would pick the overpass (sqrt(1 + 100) < 15); heights weigh 3x, sqrt(1 + 900) > 15.
    ground = [[-50, -15, 0], [50, -15, 0]]  # road on y > -15: the point is 15 m inside
    overpass = [[-50, 1, 10], [50, 1, 10]]  # road on y > 1: the point would be 1 m off
    assert Z_STRETCH == 3.0
    for order in ([ground, overpass], [overpass, ground]):
        index = _index(order)
        np.testing.assert_allclose(_signed(index, (0, 0, 0)), [-15.0], atol=1e-12)
        np.testing.assert_allclose(_signed(index, (0, 0, 10)), [1.0], atol=1e-12)  # on the overpass
    # Boxes sit on their bottom face: a 1.5 m tall box centred at z = 0.75 is at ground level.
    np.testing.assert_allclose(_box_distance(_index([ground, overpass]), 0.0, 0.0), [-14.0], atol=1e-12)


TRIANGLE = [[0, 0, 0], [10, 0, 0], [10, 3, 0], [0, 0, 0]]  # counter-clockwise: the road is inside


def test_cyclic_polyline_wraps_at_its_start() -> None:
    index = _index([TRIANGLE])
    edges = index.edges
    assert edges.prior.tolist() == [2, 0, 1] and edges.next.tolist() == [1, 2, 0]
    assert edges.convex_prior.all() and edges.convex_next.all()
    # (-1, 1) is nearest the closing vertex (0, 0): left of the first segment, right of the last
    # (the joint turns left, so the off-road side wins): outside the triangle, +sqrt(2).
    np.testing.assert_allclose(_signed(index, (-1, 1, 0)), [math.sqrt(2)], atol=1e-12)
    # Inside: 1 m from the base (2 m from x = 10, 14 / sqrt(109) from y = 0.3 x); outside: 2 m below the base.
    np.testing.assert_allclose(_signed(index, (8, 1, 0), (5, -2, 0)), [-1, 2], atol=1e-12)


def test_shorter_loop_does_not_wrap() -> None:
    # WOSAC pads polylines to the longest before wrapping, so a loop shorter than another polyline keeps
    # its end segment's own side: (-1, 1) then reads as on the road.
    index = _index([TRIANGLE, [[100, 0, 0], [110, 0, 0], [120, 0, 0], [130, 0, 0], [140, 0, 0]]])
    assert index.edges.prior[0] == -1 and index.edges.next[2] == -1
    np.testing.assert_allclose(_signed(index, (-1, 1, 0)), [-math.sqrt(2)], atol=1e-12)


def test_open_polyline_with_close_ends_only_wraps_within_tolerance() -> None:
    nearly = [[0, 0, 0], [10, 0, 0], [10, 3, 0], [0, 0.5, 0]]  # ends 0.5 m apart: 0.25 m^2 < 1
    apart = [[0, 0, 0], [10, 0, 0], [10, 3, 0], [0, 1.5, 0]]  # 2.25 m^2
    assert _index([nearly]).edges.prior[0] == 2
    assert _index([apart]).edges.prior[0] == -1


# ----------------------------------------------------------------------------------------------------------
# The k-d tree search against brute force.


def _brute_nearest(points: np.ndarray, start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """Stretched 3-D distance [M, K] from points to every segment (projection in the plane, as WOSAC)."""
    d = end - start
    to_p = points[:, None, :] - start[None]
    denom = (d[:, :2] ** 2).sum(-1)
    t = np.clip((to_p[..., :2] * d[None, :, :2]).sum(-1) / denom, 0.0, 1.0)
    off = to_p - d[None] * t[..., None]
    return np.sqrt(off[..., 0] ** 2 + off[..., 1] ** 2 + (3.0 * off[..., 2]) ** 2)


def _random_map(rng: np.random.Generator) -> list[np.ndarray]:
    polylines = []
    for _ in range(25):  # wiggly roads with short steps
        n = rng.integers(2, 40)
        steps = rng.normal(0, 1, (n, 3)) * [3.0, 3.0, 0.2]
        polylines.append(rng.uniform(-150, 150, 3) * [1, 1, 0.05] + np.cumsum(steps, axis=0))
    for _ in range(6):  # long straight edges, some sloped
        a, b = rng.uniform(-200, 200, (2, 3)) * [1, 1, 0.05]
        polylines.append(np.stack([a, b]))
    polylines.append(np.array([[-300.0, 250, 0], [300, 250, 12], [300, -250, 0]]))  # a huge corner
    return polylines


def test_kdtree_matches_brute_force() -> None:
    rng = np.random.default_rng(7)
    polylines = _random_map(rng)
    index = _index(polylines)
    edges = index.edges
    points = np.concatenate(
        [
            rng.uniform([-160, -160, -2], [160, 160, 4], (2500, 3)),  # among the edges
            rng.uniform([-600, -600, -20], [600, 600, 20], (500, 3)),  # far out, where the fallback works
            edges.start[rng.integers(0, edges.num_segments, 200)] + rng.normal(0, 0.05, (200, 3)),  # at joints
        ]
    )
    chosen = index.nearest_segment(points)
    dist = _brute_nearest(points, edges.start, edges.end)
    best = dist.min(axis=1)
    rows = np.arange(len(points))
    np.testing.assert_allclose(dist[rows, chosen], best, rtol=0, atol=1e-9)
    # The very same segment, ties (points nearest a joint) going to the lower index.
    np.testing.assert_array_equal(chosen, dist.argmin(axis=1))


def test_kdtree_falls_back_when_many_pieces_are_equally_near() -> None:
    # Near the centre of a ring of 300 segments, far more than the k searched pieces are about equally
    # far: the brute-force fallback decides.
    rng = np.random.default_rng(1)
    angle = np.linspace(0, 2 * np.pi, 301)
    ring = np.stack([40 * np.cos(angle), 40 * np.sin(angle), np.zeros(301)], -1)
    index = _index([ring, [[100, 0, 0], [200, 0, 0]]])
    points = rng.normal(0, 0.3, (300, 3)) * [1, 1, 0.1]
    dist = _brute_nearest(points, index.edges.start, index.edges.end)
    np.testing.assert_array_equal(index.nearest_segment(points), dist.argmin(axis=1))


def test_kdtree_on_a_tiny_map() -> None:
    # Fewer pieces than neighbours asked for: still exact.
    index = _index(STRAIGHT)
    assert index.nearest_segment(np.array([[0.0, 5.0, 0.0], [1e4, -1e4, 50.0]])).tolist() == [0, 0]
    two = _index([[[0, 0, 0], [1, 0, 0]], [[0, 5, 0], [1, 5, 0]]])
    assert two.nearest_segment(np.array([[0.5, 1.0, 0.0], [0.5, 4.0, 0.0]])).tolist() == [0, 1]
