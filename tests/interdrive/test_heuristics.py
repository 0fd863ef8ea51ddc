"""Each heuristic single-agent label on small constructed scenes, and the labeler on the real files."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from roads.test_index import LANE_WIDTH, ROAD_X, arc, junction_map, line, three_lane_road

from langtraj.interdrive.heuristics import (
    LABEL_RULES,
    HeuristicConfig,
    Kinematics,
    absorb_short_runs,
    label_agents,
)
from langtraj.interdrive.labels import AgentLabel, Undecided
from langtraj.interdrive.taxonomy import LABELS_BY_KEY, check_params
from langtraj.roads import MapIndex
from langtraj.runs import value_runs as runs
from langtraj.scenario import Agents, AgentType, LaneNeighbor, MapFeature, MapFeatureType, RoadMap, Scenario
from langtraj.scenario.io import read_scenario
from langtraj.scenario.windowing import cut_window

T = 91
CURRENT = 10
TIME = np.arange(T) * 0.1


def along(polyline: np.ndarray, station: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Positions and headings at arc lengths `station` along `polyline` (clamped to its ends)."""
    seg = np.diff(polyline, axis=0)
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(seg, axis=1))])
    xy = np.stack([np.interp(station, s, polyline[:, 0]), np.interp(station, s, polyline[:, 1])], axis=1)
    i = np.clip(np.searchsorted(s, station, "right") - 1, 0, len(seg) - 1)
    return xy, np.arctan2(seg[i, 1], seg[i, 0])


def scene(road_map: RoadMap, *tracks: tuple[AgentType, np.ndarray, np.ndarray]) -> Scenario:
    """A 91-step scene (current step 10) with one agent per (type, xy [T, 2], heading [T]); ids 1, 2, ..."""
    states = np.zeros((len(tracks), T, 9), np.float32)
    for a, (kind, xy, heading) in enumerate(tracks):
        states[a, :, :2] = xy
        states[a, :, 3] = heading
        states[a, :, 6:9] = (4.5, 2.0, 1.6) if kind == AgentType.VEHICLE else (0.6, 0.6, 1.8)
    agents = Agents(
        ids=np.arange(1, len(tracks) + 1),
        types=[t for t, _, _ in tracks],
        states=states,
        valid=np.ones((len(tracks), T), bool),
    )
    return Scenario("test", TIME, CURRENT, -1, agents, road_map)


def car_on_lane(y: float, speed: np.ndarray, x0: float = 0.0) -> tuple[AgentType, np.ndarray, np.ndarray]:
    """An eastbound car at lateral position `y` with per-step `speed` (m/s)."""
    x = x0 + np.concatenate([[0.0], np.cumsum(speed[:-1] * 0.1)])
    return AgentType.VEHICLE, np.stack([x, np.full(T, y)], axis=1), np.zeros(T)


def keys_of(labels: tuple[AgentLabel, ...], track_id: int = 1) -> list[str]:
    return [lab.key for lab in labels if lab.track_id == track_id]


def only(labels: tuple[AgentLabel, ...], key: str, track_id: int = 1) -> AgentLabel:
    found = [lab for lab in labels if lab.track_id == track_id and lab.key == key]
    assert len(found) == 1, f"expected one {key!r} label of track {track_id}, got {found}"
    return found[0]


def undecided_keys(undecided: tuple[Undecided, ...], track_id: int = 1) -> set[str]:
    return {u.key for u in undecided if u.track_id == track_id}


# ---------------------------------------------------------------------------------------------- building blocks


def test_runs_and_absorbing_flickers():
    seq = np.array([1, 1, 1, 2, 1, 1, 3, 3, 3, 3])
    assert runs(seq) == [(1, 0, 3), (2, 3, 4), (1, 4, 6), (3, 6, 10)]
    assert runs(absorb_short_runs(seq, 2)) == [(1, 0, 6), (3, 6, 10)]


def test_kinematics_come_from_positions_and_bridge_gaps():
    _, xy, heading = car_on_lane(0.0, np.full(T, 10.0))
    road = scene(RoadMap(), (AgentType.VEHICLE, xy, heading))
    states = road.agents.states.copy()
    states[0, :, 4] = 99.0  # wrong velocity fields are ignored
    valid = np.ones((1, T), bool)
    valid[0, 40:45] = False
    states[0, 40:45, :2] = 0.0  # garbage at invalid steps
    broken = Scenario("t", TIME, CURRENT, -1, Agents([1], [AgentType.VEHICLE], states, valid), RoadMap())
    kin = Kinematics.compute(broken, HeuristicConfig())
    assert kin.span[0].all()
    assert np.allclose(kin.speed[0, 3:-3], 10.0, atol=0.05)
    assert np.abs(kin.accel[0, 10:-10]).max() < 0.1


def test_every_registered_rule_uses_taxonomy_keys():
    for cls in LABEL_RULES.classes():
        assert set(cls.keys) <= set(LABELS_BY_KEY), cls.name


def test_config_rejects_negative_thresholds():
    with pytest.raises(ValueError, match="static_speed"):
        HeuristicConfig(static_speed=-1.0)


# ---------------------------------------------------------------------------------------------- speed profile


def test_accelerating_car_speeds_up():
    speed = np.clip(4.0 + 1.5 * (TIME - 1.0), 4.0, None)
    labels, _ = label_agents(scene(three_lane_road(), car_on_lane(0.0, speed)))
    up = only(labels, "speeding_up")
    assert up.start <= CURRENT + 2 and up.end >= T - 2
    assert "slowing_down" not in keys_of(labels) and "static" not in keys_of(labels)


def test_braking_car_slows_down():
    speed = np.clip(15.0 - 1.5 * TIME, 0.0, None)
    labels, _ = label_agents(scene(three_lane_road(), car_on_lane(0.0, speed)))
    assert "slowing_down" in keys_of(labels)
    assert "speeding_up" not in keys_of(labels) and "static" not in keys_of(labels)


def test_constant_speed_car_going_straight_in_its_lane():
    labels, undecided = label_agents(scene(three_lane_road(), car_on_lane(0.0, np.full(T, 10.0))))
    steady = only(labels, "constant_speed")
    assert (steady.start, steady.end) == (CURRENT, T)
    assert only(labels, "going_straight").end == T
    assert only(labels, "lane_position").params == {"position": "rightmost"}
    assert not {"turning_left", "turning_right", "changing_lanes", "parked", "off_main_road"} & set(keys_of(labels))
    assert not undecided


def test_stopping_car_slows_down_then_is_static():
    speed = np.clip(10.0 - 2.5 * np.clip(TIME - 2.0, 0.0, None), 0.0, None)  # stops at t = 6 s
    labels, _ = label_agents(scene(three_lane_road(), car_on_lane(0.0, speed)))
    down, still = only(labels, "slowing_down"), only(labels, "static")
    assert down.end <= still.start + 3 and still.end == T
    assert 55 <= still.start <= 66
    assert "parked" not in keys_of(labels)  # it moved during the scene


def test_slow_car_moves_slowly():
    labels, _ = label_agents(scene(three_lane_road(), car_on_lane(0.0, np.full(T, 2.0))))
    assert only(labels, "moving_slowly").start == CURRENT
    assert "static" not in keys_of(labels)


# ---------------------------------------------------------------------------------------------- parked, off road


def test_car_parked_at_the_kerb():
    labels, undecided = label_agents(scene(three_lane_road(), car_on_lane(-1.0, np.zeros(T), x0=60.0)))
    assert {"parked", "static"} <= set(keys_of(labels))
    assert "lane_position" not in keys_of(labels) and "approaching_intersection" not in keys_of(labels)
    assert not undecided


def test_car_queued_in_the_lane_is_not_parked():
    labels, _ = label_agents(scene(three_lane_road(), car_on_lane(3.5, np.zeros(T), x0=60.0)))
    assert "static" in keys_of(labels) and "parked" not in keys_of(labels)


def test_car_beside_a_lane_without_road_edges_is_parked_but_one_on_the_centre_is_undecided():
    road = three_lane_road(with_edges=False)
    beside = car_on_lane(-2.0, np.zeros(T), x0=60.0)
    centred = car_on_lane(3.5, np.zeros(T), x0=90.0)
    labels, undecided = label_agents(scene(road, beside, centred))
    assert "parked" in keys_of(labels, 1)
    assert "parked" not in keys_of(labels, 2)
    assert [u.key for u in undecided if u.track_id == 2] == ["parked"]
    assert "road edges" in undecided[0].reason


def test_car_far_from_every_lane_is_off_the_main_road():
    labels, _ = label_agents(scene(three_lane_road(), car_on_lane(30.0, np.full(T, 3.0))))
    assert only(labels, "off_main_road").start == CURRENT
    assert "lane_position" not in keys_of(labels)


# ---------------------------------------------------------------------------------------------- pulling over


def two_lane_road(with_edges: bool = True, with_neighbors: bool = True) -> RoadMap:
    """Two eastbound lanes (ids 1 and 2 at y = 0 and 3.5: rightmost and leftmost), a kerb at y = -2.75 (a 1 m
    shoulder beside the rightmost lane) and one at y = 5.25; no junction."""
    pts = line(ROAD_X[0], 0.0, ROAD_X[1], 0.0)
    last = len(pts) - 1

    def nb(feature_id: int) -> tuple[LaneNeighbor, ...]:
        return (LaneNeighbor(feature_id, 0, last, 0, last),) if with_neighbors else ()

    features = [
        MapFeature(1, MapFeatureType.LANE_SURFACE_STREET, pts, left_neighbors=nb(2)),
        MapFeature(2, MapFeatureType.LANE_SURFACE_STREET, pts + [0, LANE_WIDTH], right_neighbors=nb(1)),
    ]
    if with_edges:
        features += [
            MapFeature(10, MapFeatureType.ROAD_EDGE_BOUNDARY, pts + [0, -2.75]),
            MapFeature(11, MapFeatureType.ROAD_EDGE_BOUNDARY, pts + [0, LANE_WIDTH + 1.75]),
        ]
    return RoadMap(features)


def braking_speed(v0: float = 10.0, brake_at: float = 2.0, decel: float = 2.5) -> np.ndarray:
    """Per-step speed (m/s): `v0` until `brake_at` (s), then braking at `decel` (m/s^2) to a stop (at 6 s)."""
    return np.clip(v0 - decel * np.clip(TIME - brake_at, 0.0, None), 0.0, None)


def sideways_stop(
    dy: float, y0: float = 0.0, t0: float = 3.0, t1: float = 5.5, x0: float = 0.0
) -> tuple[AgentType, np.ndarray, np.ndarray]:
    """An eastbound car at y = `y0` braking from 10 m/s to a stop at t = 6 s (about 20 m after braking starts)
    while moving sideways by `dy` (m, left positive) between t = `t0` and `t1` (s); it stands from then on."""
    speed = braking_speed()
    x = x0 + np.concatenate([[0.0], np.cumsum(speed[:-1] * 0.1)])
    blend = np.clip((TIME - t0) / (t1 - t0), 0.0, 1.0)
    y = y0 + dy * (1 - np.cos(np.pi * blend)) / 2
    heading = np.arctan2(np.gradient(y), np.maximum(np.gradient(x), 1e-6))
    return AgentType.VEHICLE, np.stack([x, y], axis=1), heading


def test_car_drifting_to_the_right_kerb_and_stopping_pulls_over():
    labels, undecided = label_agents(scene(two_lane_road(), sideways_stop(-1.5)))
    pull = only(labels, "pulling_over")
    # The sideways motion starts at t = 3 s (window step 30); the car stands from about t = 6 s to the end.
    assert 30 <= pull.start <= 40 and pull.end == T
    still = only(labels, "static")
    assert pull.start < still.start and still.end == T
    assert "parked" not in keys_of(labels) and "changing_lanes" not in keys_of(labels)
    assert "pulling_over" not in undecided_keys(undecided)


def test_pull_over_thresholds_come_from_the_config():
    road = scene(two_lane_road(), sideways_stop(-1.5))
    assert "pulling_over" not in keys_of(label_agents(road, HeuristicConfig(pull_over_min_lateral=2.0))[0])
    assert "pulling_over" not in keys_of(label_agents(road, HeuristicConfig(pull_over_min_stop_s=4.0))[0])
    assert "pulling_over" not in keys_of(label_agents(road, HeuristicConfig(pull_over_max_edge_distance=0.5))[0])


def test_pull_over_to_a_kerb_the_map_does_not_draw_is_told_from_lane_neighbours():
    labels, _ = label_agents(scene(two_lane_road(with_edges=False), sideways_stop(-1.5)))
    assert only(labels, "pulling_over").end == T
    # From the leftmost lane to the right: the rightmost lane lies there, so that is not the road side.
    labels, _ = label_agents(scene(two_lane_road(with_edges=False), sideways_stop(-1.5, y0=LANE_WIDTH)))
    assert "pulling_over" not in keys_of(labels)
    labels, undecided = label_agents(scene(two_lane_road(with_edges=False, with_neighbors=False), sideways_stop(-1.5)))
    assert "pulling_over" not in keys_of(labels)
    assert "road side" in next(u.reason for u in undecided if u.key == "pulling_over")


def test_car_stopping_in_its_lane_behind_a_leader_does_not_pull_over():
    leader = car_on_lane(0.0, np.zeros(T), x0=30.0)  # stands in the lane centre, 10 m ahead of where the car stops
    follower = sideways_stop(0.0)
    labels, _ = label_agents(scene(two_lane_road(), follower, leader))
    assert "static" in keys_of(labels, 1) and "pulling_over" not in keys_of(labels, 1)
    assert "pulling_over" not in keys_of(labels, 2)


def test_lane_change_to_the_right_does_not_pull_over():
    # It keeps driving in the rightmost lane.
    kind, xy, heading = sideways_track(3.0, 6.0, dy=-LANE_WIDTH)
    labels, _ = label_agents(scene(two_lane_road(), (kind, xy + [0.0, LANE_WIDTH], heading)))
    assert "changing_lanes" in keys_of(labels) and "pulling_over" not in keys_of(labels)
    # It stops on the new lane's centre (a queue), not at its edge.
    labels, _ = label_agents(scene(two_lane_road(), sideways_stop(-LANE_WIDTH, y0=LANE_WIDTH)))
    assert "static" in keys_of(labels) and "pulling_over" not in keys_of(labels)


def test_parked_car_does_not_pull_over():
    labels, _ = label_agents(scene(two_lane_road(), car_on_lane(-1.5, np.zeros(T), x0=60.0)))
    assert "parked" in keys_of(labels) and "pulling_over" not in keys_of(labels)


def test_car_stopping_by_the_kerb_at_a_junction_does_not_pull_over():
    kerb = MapFeature(99, MapFeatureType.ROAD_EDGE_BOUNDARY, line(1.75, -80, 1.75, -10))
    road = RoadMap((*junction_map().features, kerb))

    def northbound_stop(stop_y: float) -> tuple[AgentType, np.ndarray, np.ndarray]:
        _, xy, _ = sideways_stop(-0.9)  # eastbound, stopping about 32.5 m from its start
        travel, right = xy[:, 0], -xy[:, 1]
        north = np.stack([right, stop_y - travel[-1] + travel], axis=1)
        heading = np.arctan2(np.gradient(north[:, 1]), np.gradient(north[:, 0]) + 1e-9)
        return AgentType.VEHICLE, north, np.where(np.gradient(north[:, 1]) > 1e-6, heading, math.pi / 2)

    labels, _ = label_agents(scene(road, northbound_stop(-15.0), northbound_stop(-45.0)))
    assert "static" in keys_of(labels, 1) and "pulling_over" not in keys_of(labels, 1)  # 5 m before the junction
    assert only(labels, "pulling_over", 2).end == T  # the same move 35 m before it


# ---------------------------------------------------------------------------------------------- junctions and turns


def junction_drive(
    path: np.ndarray, speed: float = 8.0, start: float = 40.0
) -> tuple[AgentType, np.ndarray, np.ndarray]:
    """A car driving `path` (which starts at the approach lane's start, y = -80) from station `start`."""
    xy, heading = along(path, start + speed * TIME)
    return AgentType.VEHICLE, xy, heading


APPROACH = line(0, -80, 0, -10)
LEFT_PATH = np.concatenate([APPROACH, arc(-10, -10, 10, 0.0, math.pi / 2)[1:], line(-10, 0, -80, 0)[1:]])
RIGHT_PATH = np.concatenate([APPROACH, arc(10, -10, 10, math.pi, math.pi / 2)[1:], line(10, 0, 80, 0)[1:]])
STRAIGHT_PATH = np.concatenate([APPROACH, line(0, -10, 0, 80)[1:]])


@pytest.mark.parametrize(("path", "key"), [(LEFT_PATH, "turning_left"), (RIGHT_PATH, "turning_right")])
def test_turning_through_a_junction_lane(path: np.ndarray, key: str):
    labels, _ = label_agents(scene(junction_map(), junction_drive(path)))
    turn = only(labels, key)
    crossing = only(labels, "crossing_intersection")
    approach = only(labels, "approaching_intersection")
    assert approach.start == CURRENT and approach.end == crossing.start
    assert crossing.start <= turn.start < turn.end <= crossing.end + 5
    assert "going_straight" not in keys_of(labels)


def test_going_straight_through_a_junction():
    labels, _ = label_agents(scene(junction_map(), junction_drive(STRAIGHT_PATH)))
    assert {"going_straight", "crossing_intersection", "approaching_intersection"} <= set(keys_of(labels))
    assert not {"turning_left", "turning_right"} & set(keys_of(labels))


def test_going_straight_through_a_skewed_junction():
    bend = math.radians(30.0)
    skewed = np.concatenate([APPROACH, line(0, -10, 80 * math.sin(bend), -10 + 80 * math.cos(bend))[1:]])
    labels, _ = label_agents(scene(junction_map(), junction_drive(skewed)))
    assert "going_straight" in keys_of(labels)
    assert not {"turning_left", "turning_right"} & set(keys_of(labels))


def test_car_stopped_before_a_junction_approaches_it_along_the_lane_graph():
    xy, heading = along(APPROACH, np.full(T, 45.0))  # 25 m before the junction, waiting
    labels, _ = label_agents(scene(junction_map(), (AgentType.VEHICLE, xy, heading)))
    assert only(labels, "approaching_intersection").end == T
    assert "crossing_intersection" not in keys_of(labels)


def test_approach_without_connectivity_is_undecided_unless_the_path_enters():
    xy, heading = along(APPROACH, np.full(T, 45.0))
    s = scene(junction_map(connectivity=False), (AgentType.VEHICLE, xy, heading), junction_drive(LEFT_PATH))
    linked, _ = label_agents(s)  # its lanes meet end to start: linked by geometry, the approach is decided
    assert "approaching_intersection" in keys_of(linked, 1)
    labels, undecided = label_agents(s, map_index=MapIndex.build(s.road_map, infer_links=False))
    assert "approaching_intersection" in undecided_keys(undecided, 1)
    assert "connectivity" in next(u.reason for u in undecided if u.key == "approaching_intersection")
    assert "approaching_intersection" in keys_of(labels, 2)  # its path enters the junction


# ---------------------------------------------------------------------------------------------- lane changes


def lane_change_track() -> tuple[AgentType, np.ndarray, np.ndarray]:
    """An eastbound car at 10 m/s moving from y = 0 to y = 3.5 between t = 3 s and t = 6 s."""
    x = 10.0 * TIME
    blend = np.clip((TIME - 3.0) / 3.0, 0.0, 1.0)
    y = 3.5 * (1 - np.cos(np.pi * blend)) / 2
    heading = np.arctan2(np.gradient(y), np.gradient(x))
    return AgentType.VEHICLE, np.stack([x, y], axis=1), heading


def test_lane_change_from_the_rightmost_to_the_middle_lane():
    labels, undecided = label_agents(scene(three_lane_road(), lane_change_track()))
    change = only(labels, "changing_lanes")
    assert change.params == {"from": "rightmost", "to": "middle"}
    assert 25 <= change.start <= 40 and 50 <= change.end <= 65
    position = only(labels, "lane_position")
    assert position.params == {"position": "rightmost"} and position.end == change.start
    assert not undecided


def sideways_track(
    t0: float, t1: float, dy: float = 3.5, speed: float = 10.0
) -> tuple[AgentType, np.ndarray, np.ndarray]:
    """An eastbound car at `speed` moving from y = 0 to y = `dy` between t = `t0` and `t1` (s)."""
    x = speed * TIME
    blend = np.clip((TIME - t0) / (t1 - t0), 0.0, 1.0)
    y = dy * (1 - np.cos(np.pi * blend)) / 2
    heading = np.arctan2(np.gradient(y), np.gradient(x))
    return AgentType.VEHICLE, np.stack([x, y], axis=1), heading


def test_lane_change_begun_before_the_current_step_is_seen_whole():
    labels, _ = label_agents(scene(three_lane_road(), sideways_track(0.3, 2.3)))  # switch at about step 13
    change = only(labels, "changing_lanes")
    assert change.params == {"from": "rightmost", "to": "middle"}
    assert change.start == CURRENT and change.end <= 30


def test_lane_change_whose_switch_is_before_the_current_step_is_not_labelled():
    labels, _ = label_agents(scene(three_lane_road(), sideways_track(0.0, 1.4)))  # switch at about step 7
    assert "changing_lanes" not in keys_of(labels)


def test_lane_change_still_under_way_at_the_last_step_is_left_out():
    labels, _ = label_agents(scene(three_lane_road(), sideways_track(7.0, 10.0)))
    assert "changing_lanes" not in keys_of(labels)
    kept, _ = label_agents(
        scene(three_lane_road(), sideways_track(7.0, 10.0)), HeuristicConfig(lane_change_require_settled=False)
    )
    assert only(kept, "changing_lanes").end == T


def test_lane_change_that_stops_short_of_the_new_lane_centre_still_counts():
    labels, _ = label_agents(scene(three_lane_road(), sideways_track(4.0, 6.0, dy=2.8, speed=3.0)))
    assert only(labels, "changing_lanes").params == {"from": "rightmost", "to": "middle"}


def split_middle_lane_road() -> RoadMap:
    """`three_lane_road` without its leftmost lane, the middle lane split at x = 50 into lanes 21 and 22."""
    pts = line(ROAD_X[0], 0.0, ROAD_X[1], 0.0)
    split = int(np.flatnonzero(pts[:, 0] == 50.0)[0])
    first = line(ROAD_X[0], LANE_WIDTH, 50.0, LANE_WIDTH, split + 1)
    second = line(50.0, LANE_WIDTH, ROAD_X[1], LANE_WIDTH, len(pts) - split)
    car = MapFeatureType.LANE_SURFACE_STREET
    return RoadMap(
        [
            MapFeature(
                1,
                car,
                pts,
                left_neighbors=(
                    LaneNeighbor(21, 0, split, 0, split),
                    LaneNeighbor(22, split, len(pts) - 1, 0, len(second) - 1),
                ),
            ),
            MapFeature(21, car, first, exit_lanes=(22,), right_neighbors=(LaneNeighbor(1, 0, split, 0, split),)),
            MapFeature(
                22,
                car,
                second,
                entry_lanes=(21,),
                right_neighbors=(LaneNeighbor(1, 0, len(second) - 1, split, len(pts) - 1),),
            ),
        ]
    )


def test_lane_change_into_a_lane_that_is_split_along_the_road_settles_on_its_continuation():
    # The switch is at x = 45 on lane 21, half a second before the car goes on into lane 22.
    labels, _ = label_agents(scene(split_middle_lane_road(), sideways_track(3.5, 5.5)))
    change = only(labels, "changing_lanes")
    assert change.params == {"from": "rightmost", "to": "leftmost"}
    assert 50 <= change.end <= 65


def test_lane_change_without_neighbour_lists_is_undecided():
    labels, undecided = label_agents(scene(three_lane_road(with_neighbors=False), lane_change_track()))
    assert "changing_lanes" not in keys_of(labels) and "lane_position" not in keys_of(labels)
    reasons = {u.key: u.reason for u in undecided}
    assert {"changing_lanes", "lane_position"} <= set(reasons)
    assert "neighbour" in reasons["changing_lanes"] and "left" in reasons["changing_lanes"]


def test_lane_change_with_inferred_neighbours():
    config = HeuristicConfig(infer_neighbors=True)
    labels, _ = label_agents(scene(three_lane_road(with_neighbors=False), lane_change_track()), config)
    assert only(labels, "changing_lanes").params == {"from": "rightmost", "to": "middle"}


# ---------------------------------------------------------------------------------------------- pedestrians


def pedestrian(x0: float, y0: float, vx: float, vy: float) -> tuple[AgentType, np.ndarray, np.ndarray]:
    xy = np.stack([x0 + vx * TIME, y0 + vy * TIME], axis=1)
    return AgentType.PEDESTRIAN, xy, np.full(T, math.atan2(vy, vx) if vx or vy else 0.0)


def test_pedestrian_crossing_a_crosswalk():
    labels, _ = label_agents(scene(three_lane_road(), pedestrian(42.0, -4.0, 0.0, 1.4)))
    assert only(labels, "moving").start == CURRENT
    crossing = only(labels, "crossing_street")
    assert crossing.end - crossing.start >= 50
    assert "walking_along_road" not in keys_of(labels)


def test_pedestrian_crossing_lanes_away_from_a_crosswalk():
    labels, _ = label_agents(scene(three_lane_road(with_crosswalk=False), pedestrian(120.0, -4.0, 0.0, 1.4)))
    assert "crossing_street" in keys_of(labels)


def test_pedestrian_walking_along_the_road():
    labels, _ = label_agents(scene(three_lane_road(), pedestrian(60.0, -4.0, 1.4, 0.0)))
    assert only(labels, "walking_along_road").start == CURRENT
    assert "crossing_street" not in keys_of(labels)


def test_static_pedestrian():
    labels, undecided = label_agents(scene(three_lane_road(), pedestrian(60.0, -5.0, 0.0, 0.0)))
    assert keys_of(labels) == ["static"]
    assert not undecided


# ---------------------------------------------------------------------------------------------- missing map


def test_empty_map_leaves_map_based_labels_undecided():
    moving = car_on_lane(0.0, np.full(T, 10.0))
    parked = car_on_lane(20.0, np.zeros(T), x0=100.0)
    walker = pedestrian(60.0, -4.0, 1.4, 0.0)
    labels, undecided = label_agents(scene(RoadMap(), moving, parked, walker))
    assert {"constant_speed", "going_straight"} <= set(keys_of(labels, 1))
    assert undecided_keys(undecided, 1) == {
        "off_main_road",
        "crossing_intersection",
        "approaching_intersection",
        "lane_position",
        "changing_lanes",
    }
    assert {"parked", "off_main_road"} <= undecided_keys(undecided, 2)
    assert undecided_keys(undecided, 3) == {"crossing_street", "walking_along_road"}
    assert "moving" in keys_of(labels, 3)
    assert all("no lanes" in u.reason or "no drivable lanes" in u.reason for u in undecided)


def test_agents_invalid_at_the_current_step_are_not_labelled():
    road = scene(three_lane_road(), car_on_lane(0.0, np.full(T, 10.0)))
    valid = road.agents.valid.copy()
    valid[0, : CURRENT + 1] = False
    agents = Agents(road.agents.ids, road.agents.types, road.agents.states, valid)
    labels, undecided = label_agents(Scenario("t", TIME, CURRENT, -1, agents, road.road_map))
    assert labels == () and undecided == ()


def test_a_prebuilt_map_index_is_reused():
    road = three_lane_road()
    index = MapIndex.build(road)
    one = label_agents(scene(road, car_on_lane(0.0, np.full(T, 10.0))), map_index=index)
    two = label_agents(scene(road, car_on_lane(0.0, np.full(T, 10.0))))
    assert one == two


# ---------------------------------------------------------------------------------------------- real files


def _check_valid(labels: tuple[AgentLabel, ...], scenario: Scenario) -> None:
    for lab in labels:
        check_params(lab.key, lab.params)
        assert scenario.current_index <= lab.start < lab.end <= scenario.num_steps, lab
        kind = AgentType(int(scenario.agents.types[scenario.agents.index_of(lab.track_id)]))
        assert kind in LABELS_BY_KEY[lab.key].applies_to, lab


def _moving_vehicles(scenario: Scenario) -> set[int]:
    kin = Kinematics.compute(scenario, HeuristicConfig())
    fut = slice(scenario.current_index, None)
    out = set()
    for a in np.flatnonzero(scenario.agents.types == AgentType.VEHICLE):
        valid = scenario.agents.valid[a]
        if valid[scenario.current_index] and valid[fut].mean() >= 0.5 and kin.speed[a, fut].max() > 2.0:
            out.add(int(scenario.agents.ids[a]))
    return out


@pytest.mark.real_data
def test_real_womd_scene(real_data_dir: Path):
    scenario = read_scenario(real_data_dir / "motion_data_one_scenario.tfrecord", 0)
    labels, _ = label_agents(scenario)
    _check_valid(labels, scenario)
    moving = _moving_vehicles(scenario)
    manoeuvre = {"going_straight", "turning_left", "turning_right", "crossing_intersection", "lane_position"}
    described = {lab.track_id for lab in labels if lab.key in manoeuvre}
    assert len(moving) >= 5
    assert len(moving & described) >= 0.7 * len(moving)
    speed_keys = {"speeding_up", "slowing_down", "constant_speed", "moving_slowly"}
    assert all(any(lab.key in speed_keys for lab in labels if lab.track_id == t) for t in moving)


@pytest.mark.real_data
def test_real_nuscenes_window(real_data_dir: Path):
    path = real_data_dir / "sd_nuscenes_v1.0-mini_scene-0061.pkl"
    if not path.is_file():
        pytest.skip(f"{path.name} not found in {real_data_dir}")
    scenario = cut_window(read_scenario(path, 0), 50)
    assert scenario.num_steps == 91
    labels, undecided = label_agents(scenario)
    _check_valid(labels, scenario)
    moving = _moving_vehicles(scenario)
    labelled = {lab.track_id for lab in labels}
    assert moving and len(moving & labelled) >= 0.8 * len(moving)
    reasons = {u.key: u.reason for u in undecided}
    assert "neighbour" in reasons.get("lane_position", "")  # nuScenes ScenarioNet maps have no neighbour lists
    assert any("road edges" in u.reason or "connectivity" in u.reason for u in undecided)


def test_car_stopped_on_the_lane_centre_before_a_junction_is_queued_not_parked():
    kerb = MapFeature(99, MapFeatureType.ROAD_EDGE_BOUNDARY, line(1.4, -80, 1.4, -10))
    road = RoadMap((*junction_map().features, kerb))

    def stopped_at(y: float) -> tuple[AgentType, np.ndarray, np.ndarray]:
        return AgentType.VEHICLE, np.tile([0.0, y], (T, 1)), np.full(T, math.pi / 2)

    labels, _ = label_agents(scene(road, stopped_at(-20.0), stopped_at(-70.0)))
    assert "parked" not in keys_of(labels, 1)  # 10 m before the junction, by the kerb: waiting in the queue
    assert "parked" in keys_of(labels, 2)  # 60 m before it, by the kerb
