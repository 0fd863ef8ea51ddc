"""Stop lines from a map's stop signs (`roads.stop_signs`, docs/testing.md, 'Step info'): the point of each controlled
lane nearest its sign, and which agents pass one between two steps."""

from __future__ import annotations

import math

import numpy as np

from langtraj.roads.stop_signs import StopLines
from langtraj.scenario import MapFeature, MapFeatureType, RoadMap
from langtraj.scenario.io import read_scenario

from .test_mapindex import line

LANE = MapFeatureType.LANE_SURFACE_STREET


def _map(*controlled: int) -> RoadMap:
    """An eastbound approach (1, x -50 to 0) and the junction lane after it (2, x 0 to 20); a sign 3 m right of x = 0."""
    return RoadMap(
        (
            MapFeature(1, LANE, line(-50, 0, 0, 0), exit_lanes=(2,)),
            MapFeature(2, LANE, line(0, 0, 20, 0), entry_lanes=(1,)),
            MapFeature(9, MapFeatureType.STOP_SIGN, np.array([[0.4, -3.0, 0.0]]), controlled_lanes=controlled),
        )
    )


def test_the_line_is_the_controlled_lanes_point_nearest_its_sign():
    starts = StopLines.of(_map(2))  # the junction lane that starts at the line, as WOMD's signs mostly name
    np.testing.assert_allclose(starts.points, [[0.4, 0.0]], atol=1e-9)
    np.testing.assert_allclose(starts.headings, [0.0], atol=1e-9)
    ends = StopLines.of(_map(1))  # the approach lane that ends there: its end
    np.testing.assert_allclose(ends.points, [[0.0, 0.0]], atol=1e-9)
    assert len(StopLines.of(_map(77))) == 0  # a lane the map lacks is left out
    assert len(StopLines.of(_map())) == 0


def test_an_agent_passes_a_line_going_its_lanes_way_close_to_the_lane():
    lines = StopLines.of(_map(2))
    before = np.array([[-0.5, 0.0], [-0.5, 0.0], [-0.5, 3.5], [1.0, 0.0], [0.4, -5.0]])
    now = np.array([[0.5, 0.0], [0.5, 0.0], [0.5, 3.5], [2.0, 0.0], [0.4, 5.0]])
    heading = np.array([0.0, math.pi, 0.0, 0.0, math.pi / 2])
    # over it; the wrong way; a lane over; already past; across it
    assert lines.passed(before, now, heading).tolist() == [True, False, False, False, False]
    assert StopLines.of(RoadMap(())).passed(before, now, heading).tolist() == [False] * 5


def test_the_real_scenes_signs_give_lines_beside_them(real_data_dir):
    scenario = read_scenario(real_data_dir / "sd_training.tfrecord-00000-of-01000_8a346109094cd5aa.pkl", 0)
    signs = [f for f in scenario.road_map if f.type == MapFeatureType.STOP_SIGN]
    lines = StopLines.of(scenario.road_map)
    assert len(lines) == sum(len(s.controlled_lanes) for s in signs) == 27
    nearest = np.min([np.hypot(*(lines.points - s.points[0, :2]).T) for s in signs], axis=0)
    assert nearest.max() < 9.0  # every line within a road's width of a sign
