"""The one polyline geometry (`langtraj.polylines`): arc lengths, resampling, points at a station, projections onto
segments and onto a polyline, degenerate input included, and its agreement with the torch projection of the
guidance costs (`guidance.geometry`)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from langtraj.errors import InputError
from langtraj.guidance import geometry
from langtraj.polylines import (
    arc_lengths,
    point_at,
    project_on_polyline,
    project_on_segments,
    ray_meets_polyline,
    resample,
)

ELL = np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 4.0]])  # east 3 m, then north 4 m


def test_arc_lengths_of_a_polyline_one_point_repeated_points_and_none():
    assert arc_lengths(ELL).tolist() == [0.0, 3.0, 7.0]
    assert arc_lengths(np.array([[0.0, 0.0, 5.0], [3.0, 4.0, -5.0]])).tolist() == [0.0, 5.0]  # z ignored
    assert arc_lengths(np.array([[1.0, 1.0], [1.0, 1.0], [1.0, 2.0]])).tolist() == [0.0, 0.0, 1.0]
    assert arc_lengths(ELL[:1]).tolist() == [0.0]
    assert arc_lengths(np.zeros((0, 2))).shape == (0,)


def test_resample_takes_equal_steps_of_at_most_the_spacing_and_drops_repeated_points():
    line = resample(np.array([[0.0, 0.0], [10.0, 0.0]]), 3.0)
    assert np.allclose(line, np.stack([np.linspace(0, 10, 5), np.zeros(5)], -1))  # 4 steps of 2.5 m
    ell = resample(ELL, 1.0)
    assert np.allclose(np.diff(arc_lengths(ell)), 1.0) and len(ell) == 8
    assert np.array_equal(ell[[0, -1]], ELL[[0, -1]]) and np.allclose(ell[3], [3.0, 0.0])
    repeated = np.array([[0.0, 0.0], [0.0, 0.0], [3.0, 0.0], [3.0, 0.0], [3.0, 4.0], [3.0, 4.0]])
    assert np.array_equal(resample(repeated, 1.0), ell)
    assert np.array_equal(resample(np.array([[0.0, 0.0], [0.5, 0.0]]), 1.0), [[0.0, 0.0], [0.5, 0.0]])


def test_resample_of_a_polyline_without_length_is_one_point_and_of_none_is_empty():
    assert np.array_equal(resample(np.array([[2.0, 1.0, 7.0]] * 3), 1.0), [[2.0, 1.0]])
    assert np.array_equal(resample(np.array([[2.0, 1.0]]), 1.0), [[2.0, 1.0]])
    assert resample(np.zeros((0, 3)), 1.0).shape == (0, 2)


def test_point_at_a_station_is_clamped_to_the_ends_and_vectorised():
    assert np.allclose(point_at(ELL, 5.0), [3.0, 2.0]) and point_at(ELL, 5.0).shape == (2,)
    assert np.allclose(point_at(ELL, np.array([-1.0, 0.0, 1.5, 100.0])), [[0, 0], [0, 0], [1.5, 0], [3, 4]])
    assert np.allclose(point_at(np.array([[0.0, 0.0], [0.0, 0.0], [2.0, 0.0]]), 1.0), [1.0, 0.0])  # repeated
    assert np.array_equal(point_at(ELL[1:2], 4.0), [3.0, 0.0])  # one point: that point
    with pytest.raises(InputError, match="no points"):
        point_at(np.zeros((0, 2)), 0.0)


def test_projection_onto_segments_left_right_beyond_an_end_and_on_a_zero_length_segment():
    a, b = np.array([0.0, 0.0]), np.array([10.0, 0.0])
    points = np.array([[4.0, 2.0], [4.0, -2.0], [13.0, 4.0], [12.0, 0.0], [5.0, 0.0]])
    found = project_on_segments(points, a, b, station=100.0)
    assert np.allclose(found.t, [0.4, 0.4, 1.0, 1.0, 0.5])
    assert np.allclose(found.closest, [[4, 0], [4, 0], [10, 0], [10, 0], [5, 0]])
    assert np.allclose(found.distance, [2.0, 2.0, 5.0, 2.0, 0.0])
    assert found.side.tolist() == [1.0, -1.0, 1.0, 0.0, 0.0]
    assert np.allclose(found.offset, [2.0, -2.0, 5.0, 2.0, 0.0])  # on the segment's line counts as left
    assert np.allclose(found.station, [104.0, 104.0, 110.0, 110.0, 105.0])
    point = project_on_segments(np.array([3.0, 4.0]), a, a, station=7.0)  # a zero-length segment: its start
    assert (point.t, point.distance, point.station) == (0.0, 5.0, 7.0) and np.array_equal(point.closest, a)


def test_projection_onto_segments_broadcasts_points_against_candidate_segments():
    start = np.array([[0.0, 0.0], [0.0, 0.0]])
    end = np.array([[10.0, 0.0], [0.0, 10.0]])  # east, north
    found = project_on_segments(np.array([[2.0, 1.0], [1.0, 3.0]])[:, None], start, end)  # [2, 2]
    assert found.distance.shape == (2, 2) and found.closest.shape == (2, 2, 2)
    assert np.allclose(found.distance, [[1.0, 2.0], [3.0, 1.0]])
    assert np.allclose(found.offset, [[1.0, -2.0], [3.0, -1.0]])  # left of east, right of north


def test_projection_onto_a_polyline_picks_the_nearest_segment():
    points = np.array([[1.0, 1.0], [5.0, 2.0], [2.0, -1.0], [3.0, 9.0], [-2.0, 0.0]])
    found = project_on_polyline(points, ELL)
    assert found.segment.tolist() == [0, 1, 0, 1, 0]
    assert np.allclose(found.distance, [1.0, 2.0, 1.0, 5.0, 2.0])
    assert np.allclose(found.offset, [1.0, -2.0, -1.0, 5.0, 2.0])  # (3, 9) and (-2, 0) lie on a segment's line
    assert np.allclose(found.station, [1.0, 5.0, 2.0, 7.0, 0.0])
    grid = project_on_polyline(points.reshape(5, 1, 2) + np.zeros((1, 3, 1)), ELL)  # any leading shape
    assert grid.station.shape == (5, 3) and np.allclose(grid.station, found.station[:, None])
    single = project_on_polyline(np.array([5.0, 2.0]), ELL)  # one point [2]: 0-d results
    assert single.station.shape == () and float(single.station) == pytest.approx(5.0)


def test_projection_onto_degenerate_polylines():
    one = project_on_polyline(np.array([[3.0, 4.0], [0.0, 1.0]]), np.array([[0.0, 0.0]]))
    assert one.distance.tolist() == [5.0, 1.0] and one.station.tolist() == [0.0, 0.0]
    repeated = np.array([[0.0, 0.0], [0.0, 0.0], [10.0, 0.0], [10.0, 0.0]])
    found = project_on_polyline(np.array([[5.0, 1.0], [-1.0, 0.0], [12.0, -1.0]]), repeated)
    assert found.segment.tolist() == [1, 0, 1]  # at the ends a zero-length segment is as near: the first counts
    assert np.allclose(found.station, [5.0, 0.0, 10.0]) and np.allclose(found.distance, [1.0, 1.0, np.sqrt(5)])
    with pytest.raises(InputError, match="no points"):
        project_on_polyline(np.zeros((1, 2)), np.zeros((0, 2)))


def test_numpy_and_torch_projections_agree_on_random_points():
    rng = np.random.default_rng(7)
    heading = np.cumsum(rng.normal(0.0, 0.3, 40))
    path = np.cumsum(np.stack([np.cos(heading), np.sin(heading)], -1) * rng.uniform(0.5, 4.0, (40, 1)), 0)
    path = np.concatenate([path[:10], path[9:10], path[10:]])  # one repeated point: a zero-length segment
    points = path[rng.integers(0, len(path), 500)] + rng.normal(0.0, 6.0, (500, 2))
    found = project_on_polyline(points, path)
    arc = torch.as_tensor(arc_lengths(path)[:-1])
    start, end = torch.as_tensor(path[:-1]), torch.as_tensor(path[1:])
    offset, station = geometry.offset_and_station(torch.as_tensor(points), start, end, arc)
    segment = geometry.nearest_segment(torch.as_tensor(points), start, end).numpy()
    assert np.allclose(offset.norm(dim=-1).numpy(), found.distance, atol=1e-9)
    same = segment == found.segment
    assert same.mean() > 0.99  # the same segment but at ties
    direction = (end - start)[segment].numpy()
    length = np.maximum(np.linalg.norm(direction, axis=-1, keepdims=True), 1e-12)
    normal = np.stack([-direction[:, 1], direction[:, 0]], -1) / length
    t = project_on_segments(points, path[:-1][found.segment], path[1:][found.segment]).t
    inner = same & (t > 0) & (t < 1)  # torch's station is not clamped to a segment: compare where it needs no clamp
    assert inner.mean() > 0.5
    assert np.allclose(station.numpy()[inner], found.station[inner], atol=1e-9)
    assert np.allclose((offset.numpy() * normal).sum(-1)[inner], found.offset[inner], atol=1e-9)


def test_a_ray_meets_a_polyline_at_its_first_crossing_ahead_within_the_stations_asked():
    path = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]])  # east, north, west: 30 m
    station, along = ray_meets_polyline(np.array([5.0, -5.0]), math.pi / 2, path)  # north from below the first leg
    assert station == pytest.approx(5.0) and along == pytest.approx(5.0)
    station, along = ray_meets_polyline(np.array([5.0, -5.0]), math.pi / 2, path, first_m=10.0)  # its third leg
    assert station == pytest.approx(25.0) and along == pytest.approx(15.0)
    assert ray_meets_polyline(np.array([5.0, -5.0]), -math.pi / 2, path) is None  # behind it
    assert ray_meets_polyline(np.array([5.0, -5.0]), 0.0, path) is None  # parallel to the first leg, below it
    assert ray_meets_polyline(np.array([5.0, -5.0]), math.pi / 2, path, last_m=4.0) is None
