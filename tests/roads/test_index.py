"""Map queries of the heuristic labeler on small constructed maps (also the map builders of test_heuristics)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from langtraj.roads import MapIndex, SegmentSet
from langtraj.scenario import LaneNeighbor, MapFeature, MapFeatureType, RoadMap

LANE_WIDTH = 3.5
ROAD_X = (-100.0, 300.0)


def line(x0: float, y0: float, x1: float, y1: float, num: int = 41) -> np.ndarray:
    """A straight polyline of `num` points."""
    return np.stack([np.linspace(x0, x1, num), np.linspace(y0, y1, num)], axis=1)


def arc(cx: float, cy: float, radius: float, a0: float, a1: float, num: int = 31) -> np.ndarray:
    """A circular arc from angle `a0` to `a1` (radians, counter-clockwise when a1 > a0)."""
    angles = np.linspace(a0, a1, num)
    return np.stack([cx + radius * np.cos(angles), cy + radius * np.sin(angles)], axis=1)


def three_lane_road(with_neighbors: bool = True, with_edges: bool = True, with_crosswalk: bool = True) -> RoadMap:
    """Three eastbound lanes (ids 1, 2, 3 at y = 0, 3.5, 7: rightmost to leftmost), road edges 1.75 m outside
    them and a crosswalk across the road at x in [40, 44]."""
    pts = line(ROAD_X[0], 0.0, ROAD_X[1], 0.0)
    last = len(pts) - 1

    def nb(feature_id: int) -> tuple[LaneNeighbor, ...]:
        return (LaneNeighbor(feature_id, 0, last, 0, last),) if with_neighbors else ()

    features = [
        MapFeature(1, MapFeatureType.LANE_SURFACE_STREET, pts, left_neighbors=nb(2)),
        MapFeature(
            2, MapFeatureType.LANE_SURFACE_STREET, pts + [0, LANE_WIDTH], left_neighbors=nb(3), right_neighbors=nb(1)
        ),
        MapFeature(3, MapFeatureType.LANE_SURFACE_STREET, pts + [0, 2 * LANE_WIDTH], right_neighbors=nb(2)),
    ]
    if with_edges:
        features += [
            MapFeature(10, MapFeatureType.ROAD_EDGE_BOUNDARY, pts + [0, -LANE_WIDTH / 2]),
            MapFeature(11, MapFeatureType.ROAD_EDGE_BOUNDARY, pts + [0, 2.5 * LANE_WIDTH]),
        ]
    if with_crosswalk:
        features.append(MapFeature(20, MapFeatureType.CROSSWALK, [[40, -1.75], [44, -1.75], [44, 8.75], [40, 8.75]]))
    return RoadMap(features)


def junction_map(interpolating: bool = True, connectivity: bool = True) -> RoadMap:
    """A northbound approach lane (1) ending at (0, -10), three junction lanes (left 11 to the west, straight 12,
    right 13 to the east) and their exit lanes (21, 22, 23), plus an eastbound cross lane (30) the straight
    and left-turn lanes cross."""
    approach = line(0, -80, 0, -10)
    left = arc(-10, -10, 10, 0.0, math.pi / 2)  # starts heading north at (0, -10), ends heading west at (-10, 0)
    right = arc(10, -10, 10, math.pi, math.pi / 2)  # starts heading north at (0, -10), ends heading east at (10, 0)
    straight = line(0, -10, 0, 10, 21)

    def links(*ids: int) -> tuple[int, ...]:
        return ids if connectivity else ()

    return RoadMap(
        [
            MapFeature(1, MapFeatureType.LANE_SURFACE_STREET, approach, exit_lanes=links(11, 12, 13)),
            MapFeature(11, MapFeatureType.LANE_SURFACE_STREET, left, entry_lanes=links(1), exit_lanes=links(21),
                       interpolating=interpolating),
            MapFeature(12, MapFeatureType.LANE_SURFACE_STREET, straight, entry_lanes=links(1), exit_lanes=links(22),
                       interpolating=interpolating),
            MapFeature(13, MapFeatureType.LANE_SURFACE_STREET, right, entry_lanes=links(1), exit_lanes=links(23),
                       interpolating=interpolating),
            MapFeature(21, MapFeatureType.LANE_SURFACE_STREET, line(-10, 0, -80, 0), entry_lanes=links(11)),
            MapFeature(22, MapFeatureType.LANE_SURFACE_STREET, line(0, 10, 0, 80), entry_lanes=links(12)),
            MapFeature(23, MapFeatureType.LANE_SURFACE_STREET, line(10, 0, 80, 0), entry_lanes=links(13)),
            MapFeature(30, MapFeatureType.LANE_SURFACE_STREET, line(-30, -3, 30, -3)),
        ]
    )  # fmt: skip


def lane_index(index: MapIndex, feature_id: int) -> int:
    return int(np.flatnonzero(index.lane_ids == feature_id)[0])


# ---------------------------------------------------------------------------------------------- segment grid


def test_segment_candidates_find_every_segment_within_radius():
    rng = np.random.default_rng(3)
    lines = [np.cumsum(rng.normal(0, 2.0, (30, 2)), axis=0) + rng.uniform(-40, 40, 2) for _ in range(12)]
    segs = SegmentSet.build(lines)
    queries = rng.uniform(-50, 50, (300, 2))
    query, seg = segs.candidates(queries, 4.0)
    dist, _, _ = segs.project(queries[query], seg)
    found = {(int(q), int(s)) for q, s, d in zip(query, seg, dist, strict=True) if d <= 4.0}
    all_q = np.repeat(np.arange(len(queries)), len(segs))
    all_s = np.tile(np.arange(len(segs)), len(queries))
    all_d, _, _ = segs.project(queries[all_q], all_s)
    expected = {(int(q), int(s)) for q, s, d in zip(all_q, all_s, all_d, strict=True) if d <= 4.0}
    assert found == expected
    assert len(expected) > 50


def test_segments_are_at_most_one_metre():
    segs = SegmentSet.build([line(0, 0, 100, 0, 3)])
    assert np.linalg.norm(segs.end - segs.start, axis=1).max() <= 1.0 + 1e-9
    assert segs.station[-1] == pytest.approx(99.0, abs=1.0)


# ---------------------------------------------------------------------------------------------- lanes


def test_match_picks_the_lane_whose_heading_agrees_and_signs_the_offset():
    eastbound = MapFeature(1, MapFeatureType.LANE_SURFACE_STREET, line(0, 0, 100, 0))
    westbound = MapFeature(2, MapFeatureType.LANE_SURFACE_STREET, line(100, 1.0, 0, 1.0))
    index = MapIndex.build(RoadMap([eastbound, westbound]))
    points = np.array([[50.0, 0.8], [50.0, 0.2], [50.0, 20.0]])
    east = index.match_lanes(points, np.array([0.0, 0.0, 0.0]), radius=3.0, max_heading_diff=math.radians(45))
    assert index.lane_ids[east.lane[:2]].tolist() == [1, 1]
    assert east.lane[2] == -1 and np.isinf(east.distance[2])
    assert east.lateral[0] == pytest.approx(0.8) and east.station[0] == pytest.approx(50.0)
    west = index.match_lanes(points[:1], np.array([math.pi]), radius=3.0, max_heading_diff=math.radians(45))
    assert index.lane_ids[west.lane[0]] == 2
    assert west.lateral[0] == pytest.approx(0.2)  # south of a westbound lane is its left
    nearest = index.match_lanes(points[:1], radius=3.0)
    assert index.lane_ids[nearest.lane[0]] == 2  # without a heading the nearest centerline wins


def test_bike_lanes_are_skipped_for_drivable_matches():
    bike = MapFeature(1, MapFeatureType.LANE_BIKE_LANE, line(0, 0, 100, 0))
    index = MapIndex.build(RoadMap([bike]))
    assert not index.match_lanes([[50.0, 0.0]], radius=3.0).matched[0]
    assert index.match_lanes([[50.0, 0.0]], radius=3.0, drivable_only=False).matched[0]


def test_lane_positions_from_neighbour_lists():
    index = MapIndex.build(three_lane_road())
    assert index.neighbor_source == "map"
    positions = [index.lane_position(lane_index(index, i), 50.0) for i in (1, 2, 3)]
    assert positions == ["rightmost", "middle", "leftmost"]
    single = MapIndex.build(RoadMap([MapFeature(5, MapFeatureType.LANE_SURFACE_STREET, line(0, 0, 50, 0))]))
    assert single.neighbor_source == "none"
    assert single.lane_position(0, 10.0) == "unknown"


def test_lane_positions_unknown_without_neighbours_unless_inferred():
    road = three_lane_road(with_neighbors=False)
    assert MapIndex.build(road).lane_position(0, 50.0) == "unknown"
    inferred = MapIndex.build(road, infer_neighbors=True)
    assert inferred.neighbor_source == "geometry"
    positions = [inferred.lane_position(lane_index(inferred, i), 50.0) for i in (1, 2, 3)]
    assert positions == ["rightmost", "middle", "leftmost"]


def two_lanes_beside(kind: MapFeatureType, ends: bool = False) -> RoadMap:
    """Car lanes 1 (y = 0) and 2 (y = 3.5) going on into lanes 11 and 12, and a lane 0 of `kind` on their right
    (y = -3.5) that also goes on (into lane 10) unless it `ends`."""
    pts = line(0, 0, 100, 0)
    last = len(pts) - 1

    def nb(feature_id: int) -> tuple[LaneNeighbor, ...]:
        return (LaneNeighbor(feature_id, 0, last, 0, last),)

    car = MapFeatureType.LANE_SURFACE_STREET
    features = [
        MapFeature(0, kind, pts - [0, LANE_WIDTH], left_neighbors=nb(1), exit_lanes=() if ends else (10,)),
        MapFeature(1, car, pts, left_neighbors=nb(2), right_neighbors=nb(0), exit_lanes=(11,)),
        MapFeature(2, car, pts + [0, LANE_WIDTH], right_neighbors=nb(1), exit_lanes=(12,)),
        MapFeature(11, car, line(100, 0, 200, 0), entry_lanes=(1,)),
        MapFeature(12, car, line(100, LANE_WIDTH, 200, LANE_WIDTH), entry_lanes=(2,)),
    ]
    if not ends:
        features.append(MapFeature(10, kind, line(100, -LANE_WIDTH, 200, -LANE_WIDTH), entry_lanes=(0,)))
    return RoadMap(features)


def test_a_bike_lane_beside_the_rightmost_car_lane_does_not_make_it_a_middle_lane():
    index = MapIndex.build(two_lanes_beside(MapFeatureType.LANE_BIKE_LANE))
    assert [index.lane_position(lane_index(index, i), 50.0) for i in (1, 2)] == ["rightmost", "leftmost"]
    assert index.lane_position(lane_index(index, 0), 50.0) == "single"  # the only bike lane there
    cars = MapIndex.build(two_lanes_beside(MapFeatureType.LANE_SURFACE_STREET))
    assert [cars.lane_position(lane_index(cars, i), 50.0) for i in (0, 1, 2)] == ["rightmost", "middle", "leftmost"]


def test_a_lane_that_ends_beside_the_road_does_not_count_for_the_others():
    index = MapIndex.build(two_lanes_beside(MapFeatureType.LANE_SURFACE_STREET, ends=True))
    assert index.is_ending.tolist() == [i == lane_index(index, 0) for i in range(index.num_lanes)]
    assert [index.lane_position(lane_index(index, i), 50.0) for i in (0, 1, 2)] == [
        "rightmost",
        "rightmost",
        "leftmost",
    ]
    # A change into or out of the ending lane places both lanes among all the lanes there.
    assert index.lane_position(lane_index(index, 1), 50.0, with_ending=True) == "middle"
    # Without exit lanes anywhere (a map cut across the road) no lane counts as ending.
    cut = MapIndex.build(
        RoadMap([f for f in two_lanes_beside(MapFeatureType.LANE_SURFACE_STREET).features if f.id < 10])
    )
    assert not cut.is_ending.any()


def test_neighbour_side_counts_neighbours_not_exit_lanes():
    road = three_lane_road()
    ahead = MapFeature(4, MapFeatureType.LANE_SURFACE_STREET, line(ROAD_X[1], 0, ROAD_X[1] + 50, 0), entry_lanes=(1,))
    index = MapIndex.build(RoadMap([*road.features, ahead]))
    right, middle, left, nxt = (lane_index(index, i) for i in (1, 2, 3, 4))
    assert index.neighbor_side(right, middle, np.array([50.0, 1.7])) == "left"
    assert index.neighbor_side(middle, right, np.array([50.0, 1.7])) == "right"
    assert index.neighbor_side(right, left, np.array([50.0, 3.0])) is None
    assert index.neighbor_side(right, nxt, np.array([ROAD_X[1], 0.0])) is None
    assert index.geometric_side(right, middle, np.array([50.0, 1.7])) == "left"


def test_neighbour_side_per_lane_pair_for_the_detector():
    # With lists: a listed pair is beside, either way round; a pair listed with others (1 and 3) is not.
    index = MapIndex.build(three_lane_road(with_crosswalk=False))
    right, middle, left = (lane_index(index, i) for i in (1, 2, 3))
    assert index.neighbor_side(right, middle, per_lane=True) == "left"
    assert index.neighbor_side(middle, right, per_lane=True) == "right"
    assert index.neighbor_side(right, left, per_lane=True, band=(0.0, 10.0)) is None
    # Without lists: lanes `band` apart beside each other (2-5 m for the detector), never an exit lane.
    bare = three_lane_road(with_neighbors=False, with_edges=False, with_crosswalk=False)
    ahead = MapFeature(4, MapFeatureType.LANE_SURFACE_STREET, line(ROAD_X[1], 0, ROAD_X[1] + 5, 0), entry_lanes=(1,))
    index = MapIndex.build(RoadMap([*bare.features, ahead]))
    right, middle, left, nxt = (lane_index(index, i) for i in (1, 2, 3, 4))
    assert index.neighbor_side(right, middle, per_lane=True, band=(2.0, 5.0)) == "left"
    assert index.neighbor_side(middle, right, per_lane=True, band=(2.0, 5.0)) == "right"
    assert index.neighbor_side(right, left, per_lane=True, band=(2.0, 5.0)) is None  # 7 m apart
    assert index.neighbor_side(right, middle, per_lane=True, band=(4.0, 5.0)) is None
    assert index.neighbor_side(nxt, right, per_lane=True, band=(0.0, 10.0)) is None  # 4 names 1 its entry lane


def test_parked_decision_road_side_and_kerb():
    index = MapIndex.build(three_lane_road(with_crosswalk=False))
    beside = np.array([[50.0, -1.2]])  # 1.2 m right of the rightmost lane centre, 0.55 m from the edge
    match = index.match_lanes(beside, radius=2.0)
    assert index.parked_decision(index.match_lanes(np.array([[50.0, -30.0]]), radius=2.0), beside)[0] is True
    assert index.parked_decision(match, beside)[0] is False  # on a lane: the detector asks no more
    assert index.parked_decision(match, beside, lane_offset=1.0)[0] is True
    assert index.parked_decision(match, beside, lane_offset=1.5, kerb_distance=1.0)[0] is True
    assert index.parked_decision(match, beside, lane_offset=1.5, kerb_distance=0.3)[0] is False
    no_edges = MapIndex.build(three_lane_road(with_edges=False, with_crosswalk=False))
    assert no_edges.parked_decision(match, beside, kerb_distance=1.0)[0] is None
    assert MapIndex.build(RoadMap([])).parked_decision(match, beside)[0] is None


# ---------------------------------------------------------------------------------------------- junctions


def test_junction_lanes_from_the_interpolating_flag():
    index = MapIndex.build(junction_map(interpolating=True))
    assert index.junction_source == "map"
    flagged = {int(i) for i in index.lane_ids[index.is_junction]}
    assert flagged == {11, 12, 13}


def test_junction_lanes_from_geometry_when_the_map_has_no_flag():
    index = MapIndex.build(junction_map(interpolating=False))
    assert index.junction_source == "geometry"
    flagged = {int(i) for i in index.lane_ids[index.is_junction]}
    # 11 and 12 cross lane 30; 13 is a short sharp turn; 30 is crossed by 11 and 12 (a junction lane too).
    assert {11, 12, 13} <= flagged
    assert not flagged & {1, 21, 22, 23}


def test_distance_to_junction_follows_exit_lanes():
    index = MapIndex.build(junction_map())
    approach = lane_index(index, 1)
    assert index.has_connectivity
    assert index.distance_to_junction(approach, 40.0) == pytest.approx(30.0, abs=0.5)
    assert index.distance_to_junction(lane_index(index, 11), 3.0) == 0.0
    assert math.isinf(index.distance_to_junction(lane_index(index, 22), 0.0))
    unlinked = MapIndex.build(junction_map(connectivity=False))  # linked from geometry: lanes meet end to start
    assert unlinked.connectivity_source == "geometry" and index.connectivity_source == "map"
    assert unlinked.exits == index.exits
    assert unlinked.distance_to_junction(lane_index(unlinked, 1), 40.0) == pytest.approx(30.0, abs=0.5)


# ---------------------------------------------------------------------------------------------- areas and edges


def test_crosswalk_containment_and_road_edge_distance():
    index = MapIndex.build(three_lane_road())
    inside = index.in_crosswalk(np.array([[42.0, 3.0], [45.0, 3.0], [42.0, -2.0]]))
    assert inside.tolist() == [True, False, False]
    dist = index.distance_to_road_edge(np.array([[50.0, -1.0], [50.0, 3.5]]), radius=2.0)
    assert dist[0] == pytest.approx(0.75)
    assert math.isinf(dist[1])


def test_empty_map_has_nothing():
    index = MapIndex.build(RoadMap())
    assert not (index.has_lanes or index.has_road_edges or index.has_crosswalks or index.has_connectivity)
    assert index.junction_source == "none" and index.neighbor_source == "none"
    assert not index.match_lanes(np.zeros((3, 2)), radius=3.0).matched.any()
    assert np.isinf(index.distance_to_road_edge(np.zeros((2, 2)), 5.0)).all()
