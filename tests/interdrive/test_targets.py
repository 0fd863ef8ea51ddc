"""Targets from the map (`interdrive.targets`): per behaviour kind on constructed maps, the target is the right
lanes, stop point, kerb line or conflict point."""

from __future__ import annotations

import math

import numpy as np
import pytest

from langtraj.interdrive.behaviour import Behaviour
from langtraj.interdrive.mapindex import MapIndex
from langtraj.interdrive.targets import TargetUnavailable, derive_target, point_at_station, stations

from .test_counterfactual import HALF, LEFT_LANE_STRAIGHT, RIGHT_LANE_STRAIGHT, drive, four_way, two_lane_road
from .test_heuristics import TIME, along, scene
from .test_mapindex import line


def _target(s, track, behaviour, other=None):
    return derive_target(s, track, behaviour, MapIndex.build(s.road_map), other_id=other)


def _end_heading(path: np.ndarray) -> float:
    d = path[-1] - path[-5]
    return math.atan2(d[1], d[0])


def test_a_right_turn_follows_the_right_turn_lane_and_its_exit_and_its_goal_lies_past_the_junction():
    s = scene(four_way(), drive(RIGHT_LANE_STRAIGHT))  # northbound in the right lane, 31 m before the junction
    target = _target(s, 1, Behaviour.TURN_RIGHT)
    assert abs(_end_heading(target.path)) < 0.1  # heading east, on the exit lane 24 (y = -1.75)
    assert np.allclose(target.path[-1, 1], -HALF, atol=0.2) and target.path[-1, 0] > 15
    goal = target.goal_point
    assert goal[0] > 10.0 and abs(goal[1] + HALF) < 0.5  # past the junction's exit (x = 10), on the exit lane
    straight = _target(s, 1, Behaviour.GO_STRAIGHT)
    assert abs(_end_heading(straight.path) - math.pi / 2) < 0.1 and np.allclose(straight.path[-1, 0], HALF, atol=0.2)


def test_a_turn_the_lane_does_not_allow_has_no_target():
    s = scene(four_way(), drive(RIGHT_LANE_STRAIGHT))
    with pytest.raises(TargetUnavailable, match="@1 cannot turn left: no such branch"):
        _target(s, 1, Behaviour.TURN_LEFT)


def test_a_left_lane_change_targets_the_left_neighbour_lane_and_a_right_one_is_unavailable():
    s = scene(two_lane_road(), _eastbound(y=0.0))
    target = _target(s, 1, Behaviour.LANE_CHANGE_LEFT)
    arc = stations(target.path)
    on_lane = target.path[arc > target.lateral_from + 1.0]
    assert np.allclose(on_lane[:, 1], 3.5, atol=0.05)  # the left lane's centreline
    assert on_lane[0, 0] > s.agents.states[0, s.current_index, 0] + 4.0  # from where a change can begin
    with pytest.raises(TargetUnavailable, match="no lane on its right"):
        _target(s, 1, Behaviour.LANE_CHANGE_RIGHT)


def test_a_stop_lies_at_the_stop_line_when_comfortable_braking_reaches_it_and_short_of_it_otherwise():
    s = scene(four_way(), drive(LEFT_LANE_STRAIGHT, speed=8.0, start=35.0))  # 27 m before the junction at 8 m/s
    stop = _target(s, 1, Behaviour.STOP)
    assert stop.stop and stop.speed == 0.0 and "stop line" in stop.reason
    assert np.allclose(stop.goal_point, [-HALF, -11.0], atol=0.3)  # 1 m before the junction lanes start (y = -10)
    fast = scene(four_way(), drive(LEFT_LANE_STRAIGHT, speed=12.0, start=35.0))  # 23 m; braking needs 36 m + half a car
    early = _target(fast, 1, Behaviour.STOP)
    assert "braking" in early.reason and early.goal_point[1] > -10.0 - 1e-6  # beyond the line: no line to stop at


def test_a_pull_over_shifts_to_the_kerb_side_and_stops_ahead():
    s = scene(four_way(), drive(RIGHT_LANE_STRAIGHT, speed=6.0, start=0.0))
    target = _target(s, 1, Behaviour.PULL_OVER)
    goal = target.goal_point
    assert target.stop and goal[1] > s.agents.states[0, s.current_index, 1] + 5.0
    assert goal[0] > HALF + 0.75  # right of the lane centre (no road edges here: half a lane)
    start = point_at_station(target.path, 0.0)
    assert abs(start[0] - HALF) < 0.1  # the shift starts from the lane centre


def test_yielding_and_going_first_meet_at_the_conflict_point_of_crossing_lanes():
    eastbound = _track(line(-80, -HALF, -10, -HALF), 8.0, 40.0)  # on lane 41 at x = -32 (8 m/s)
    s = scene(four_way(), drive(LEFT_LANE_STRAIGHT), eastbound)
    give = _target(s, 1, Behaviour.YIELD, other=2)
    go = _target(s, 1, Behaviour.GO_FIRST, other=2)
    assert give.conflict is not None and np.allclose(give.conflict, [-HALF, -HALF], atol=1.5)
    assert give.first is False and go.first is True and give.other_id == 2
    assert give.other_eta == pytest.approx((80.0 - 48.0 - HALF) / 8.0, abs=0.3)  # at x = -32 now, 8 m/s to x = -1.75


def _eastbound(y: float, speed: float = 10.0):
    from langtraj.scenario import AgentType

    xy = np.stack([speed * TIME, np.full_like(TIME, y)], axis=1)
    return AgentType.VEHICLE, xy, np.zeros_like(TIME)


def _track(path: np.ndarray, speed: float, start: float):
    from langtraj.scenario import AgentType

    xy, heading = along(path[:, :2], start + speed * TIME)
    return AgentType.VEHICLE, xy, heading


def test_going_first_is_feasible_only_where_the_agent_can_get_to_the_crossing_first():
    from langtraj.interdrive.targets import order_feasibility

    far = scene(four_way(), drive(LEFT_LANE_STRAIGHT), _track(line(-80, -HALF, -10, -HALF), 8.0, 10.0))
    near = scene(four_way(), drive(LEFT_LANE_STRAIGHT), _track(line(-80, -HALF, -10, -HALF), 8.0, 50.0))
    index = MapIndex.build(far.road_map)
    assert order_feasibility(far, 1, 2, Behaviour.GO_FIRST, index).status == "feasible"  # the other is 7.5 s out
    verdict = order_feasibility(near, 1, 2, Behaviour.GO_FIRST, index)  # the other gets there in 2.5 s
    assert verdict.status == "infeasible" and "@2 gets to the crossing in 2.5 s" in verdict.reason
    assert order_feasibility(near, 1, 2, Behaviour.YIELD, index).status == "feasible"  # waiting is always possible


def test_a_lane_change_needs_room_before_the_junction_for_the_change_to_settle():
    def change_starts(s):
        target = _target(s, 1, Behaviour.LANE_CHANGE_LEFT)
        on_lane = target.path[stations(target.path) > target.lateral_from + 1.0]
        assert np.allclose(on_lane[:, 0], -HALF, atol=0.2)  # the left lane, before or after the junction
        return on_lane[0, 1]

    far = scene(four_way(), drive(RIGHT_LANE_STRAIGHT, speed=6.0, start=0.0))  # 64 m before the junction
    near = scene(four_way(), drive(RIGHT_LANE_STRAIGHT, speed=6.0, start=50.0))  # 14 m before it
    assert change_starts(far) < -30.0  # into the left approach lane, well before the junction at y = -10
    assert change_starts(near) > 10.0  # too close to settle before it: into the left lane beyond the junction
