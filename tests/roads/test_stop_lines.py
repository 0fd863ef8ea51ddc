"""Stop lines (`roads.stop_lines`, docs/testing.md, 'Step info'): a stop sign's, the point of each lane it controls
nearest it; a signal's, its stop point on its lane; and which agents pass one between two steps."""

from __future__ import annotations

import math

import numpy as np
import pytest

from langtraj.roads.stop_lines import StopLines
from langtraj.scenario import MapFeature, MapFeatureType, RoadMap, TrafficLights
from langtraj.scenario.io import read_scenario

from .test_index import line

LANE = MapFeatureType.LANE_SURFACE_STREET


def _map(*controlled: int) -> RoadMap:
    """An eastbound approach (1, x -50 to 0) and the junction lane after it (2, x 0 to 20); a sign 3 m to their
    right at x = 0.4 controlling `controlled`."""
    return RoadMap(
        (
            MapFeature(1, LANE, line(-50, 0, 0, 0), exit_lanes=(2,)),
            MapFeature(2, LANE, line(0, 0, 20, 0), entry_lanes=(1,)),
            MapFeature(9, MapFeatureType.STOP_SIGN, np.array([[0.4, -3.0, 0.0]]), controlled_lanes=controlled),
        )
    )


def test_the_line_is_the_controlled_lanes_point_nearest_its_sign():
    starts = StopLines.of_signs(_map(2))  # the junction lane that starts at the line, as WOMD's signs mostly name
    np.testing.assert_allclose(starts.points, [[0.4, 0.0]], atol=1e-9)
    np.testing.assert_allclose(starts.headings, [0.0], atol=1e-9)
    ends = StopLines.of_signs(_map(1))  # the approach lane that ends there: its end
    np.testing.assert_allclose(ends.points, [[0.0, 0.0]], atol=1e-9)
    assert len(StopLines.of_signs(_map(77))) == 0  # a lane the map lacks is left out
    assert len(StopLines.of_signs(_map())) == 0


def test_an_agent_passes_a_line_going_its_lanes_way_close_to_the_lane():
    lines = StopLines.of_signs(_map(2))
    before = np.array([[-0.5, 0.0], [-0.5, 0.0], [-0.5, 3.5], [1.0, 0.0], [0.4, -5.0]])
    now = np.array([[0.5, 0.0], [0.5, 0.0], [0.5, 3.5], [2.0, 0.0], [0.4, 5.0]])
    heading = np.array([0.0, math.pi, 0.0, 0.0, math.pi / 2])
    # over it; the wrong way; a lane over; already past; across it
    assert lines.passed(before, now, heading).tolist() == [True, False, False, False, False]
    assert StopLines.of_signs(RoadMap(())).passed(before, now, heading).tolist() == [False] * 5


def test_the_real_scenes_signs_give_lines_beside_them(real_data_dir):
    scenario = read_scenario(real_data_dir / "sd_training.tfrecord-00000-of-01000_8a346109094cd5aa.pkl", 0)
    signs = [f for f in scenario.road_map if f.type == MapFeatureType.STOP_SIGN]
    lines = StopLines.of_signs(scenario.road_map)
    assert len(lines) == sum(len(s.controlled_lanes) for s in signs) == 27
    nearest = np.min([np.hypot(*(lines.points - s.points[0, :2]).T) for s in signs], axis=0)
    assert nearest.max() < 9.0  # every line within a road's width of a sign


def test_a_signals_line_is_its_stop_point_heading_its_lanes_way():
    states = np.zeros((3, 2), np.int8)
    lights = TrafficLights(np.array([2, 77]), states, np.ones_like(states, bool), np.array([[0.0, 0.2, 0], [5, 5, 0]]))
    lines = StopLines.of_signals(_map(), lights)  # lane 77 is not on the map: its line heads nowhere
    np.testing.assert_allclose(lines.points, [[0.0, 0.0], [5.0, 5.0]], atol=1e-9)
    assert lines.headings[0] == pytest.approx(0.0) and math.isnan(lines.headings[1])
    each = lines.passed_each(np.array([[-0.5, 0.0], [4.5, 5.0]]), np.array([[0.5, 0.0], [5.5, 5.0]]), np.zeros(2))
    assert each.tolist() == [[True, False], [False, False]]


def test_the_real_scenes_signal_lines_lie_on_their_lanes(real_data_dir):
    scenario = read_scenario(real_data_dir / "motion_data_one_scenario.tfrecord", 0)
    lines = StopLines.of_signals(scenario.road_map, scenario.traffic_lights)
    assert len(lines) == 12 and np.isfinite(lines.headings).all()
    gap = np.hypot(*(lines.points - scenario.traffic_lights.stop_points[:, :2]).T)
    assert gap.max() < 0.5  # WOMD's stop points sit on their lanes
