"""Road edges derived from the lanes of a map without any (scenario.drivable): their geometry and side on built maps,
maps left alone, the switch, the consumers seeing one road, and the real nuScenes scene's logged vehicles."""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
import pytest
from scenario_builders import make_scenario

from langtraj.errors import InputError
from langtraj.metrics.controllability import offroad_rate
from langtraj.metrics.features import SceneMap
from langtraj.metrics.road import road_edge_index
from langtraj.rollouts.baselines import generate_baseline
from langtraj.scenario import AgentType, MapFeature, MapFeatureType, RoadMap, Scenario
from langtraj.scenario.drivable import (
    DEFAULT_LANE_WIDTH_M,
    FROM_LANES,
    FROM_LANES_AND_OUTLINE,
    SWITCH,
    derive_road_edges,
    drivable_outline_ids,
    measured_road_edges,
    road_edges_derived_from,
    with_derived_road_edges,
)
from langtraj.scenario.io import read_scenario

HALF = DEFAULT_LANE_WIDTH_M / 2
NUSCENES_0061 = "sd_nuscenes_v1.0-mini_scene-0061.pkl"


def lane(feature_id: int, *xy: tuple[float, float], step: float = 1.0) -> MapFeature:
    """A lane through the points `xy`, resampled to about `step` m."""
    corners = np.asarray(xy, float)
    pieces = [
        np.linspace(a, b, max(int(np.hypot(*(b - a)) / step), 1), endpoint=False)
        for a, b in itertools.pairwise(corners)
    ]
    points = np.concatenate([*pieces, corners[-1:]])
    return MapFeature(feature_id, MapFeatureType.LANE_SURFACE_STREET, np.c_[points, np.zeros(len(points))])


def with_map(*features: MapFeature) -> Scenario:
    return replace(make_scenario(), road_map=RoadMap(features))


def signed(edges: list[MapFeature] | tuple[MapFeature, ...], *xy: tuple[float, float]) -> np.ndarray:
    """The metrics' signed distance (positive off the road) of points at z = 0."""
    index = road_edge_index([f.points for f in edges])
    return index.signed_distance(np.array([[x, y, 0.0] for x, y in xy]))


def ring_area(feature: MapFeature) -> float:
    """Shoelace area of a closed ring: positive counter-clockwise."""
    x, y = feature.points[:, 0], feature.points[:, 1]
    return 0.5 * float((x[:-1] * y[1:] - x[1:] * y[:-1]).sum())


def test_a_straight_lane_has_edges_half_a_lane_either_side_with_the_road_on_their_left():
    edges = derive_road_edges(RoadMap((lane(1, (0, 0), (100, 0)),)))
    assert len(edges) == 1
    ring = edges[0]
    assert ring.type is MapFeatureType.ROAD_EDGE_BOUNDARY and ring.derived_from == FROM_LANES and ring.id == 2
    np.testing.assert_array_equal(ring.points[0], ring.points[-1])  # closed
    assert (ring.points[:, 2] == 0).all() and ring_area(ring) > 0  # flat, counter-clockwise
    along = ring.points[(ring.points[:, 0] > 0) & (ring.points[:, 0] < 100)]
    assert (along[:, 1] > 0).any() and (along[:, 1] < 0).any()
    np.testing.assert_allclose(np.abs(along[:, 1]), HALF, atol=1e-9)  # the two sides at +-half a lane width
    on_road, beyond_left, beyond_right = signed(edges, (50, 0), (50, HALF + 3), (50, -HALF - 3))
    assert on_road == pytest.approx(-HALF)
    assert beyond_left == pytest.approx(3) and beyond_right == pytest.approx(3)


def test_a_lane_polygon_is_used_where_the_file_gives_one():
    outline = [[0, -3, 0], [100, -3, 0], [100, 2, 0], [0, 2, 0]]
    wide = replace(lane(1, (0, 0), (100, 0)), polygon=outline)
    edges = derive_road_edges(RoadMap((wide,)))
    assert signed(edges, (50, -2.5), (50, 1.5)).max() < 0  # inside the outline, beyond half a default lane
    assert signed(edges, (50, 2.5))[0] == pytest.approx(0.5, abs=0.01)


def test_a_junction_of_crossing_lanes_is_one_ring_without_inner_edges():
    lanes = [
        lane(1, (-60, -HALF), (60, -HALF)),  # eastbound
        lane(2, (60, HALF), (-60, HALF)),  # westbound
        lane(3, (HALF, -60), (HALF, 60)),  # northbound
        lane(4, (-HALF, 60), (-HALF, -60)),  # southbound
        lane(5, (-10, -HALF), (-4, -3), (-HALF, -10)),  # a right turn
        lane(6, (HALF, -10), (-2, 2), (-10, HALF)),  # a left turn
    ]
    edges = derive_road_edges(RoadMap(tuple(lanes)))
    assert len(edges) == 1 and ring_area(edges[0]) > 0  # one outer ring, no hole
    assert signed(edges, (0, 0), (-1, -1), (30, 1), (1, 30)).max() < 0
    assert signed(edges, (20, 20), (-20, -20)).min() > 0


def test_holes_are_islands_with_the_road_outside_and_tiny_ones_are_filled():
    block = [(0, 0), (60, 0), (60, 60), (0, 60), (0, 0)]
    edges = derive_road_edges(RoadMap((lane(1, *block),)))
    assert len(edges) == 2
    outer, hole = sorted(edges, key=ring_area, reverse=True)
    assert ring_area(outer) > 0 > ring_area(hole)  # the island's ring runs clockwise: the road on its left
    assert signed(edges, (30, 30))[0] > 20 and signed(edges, (30, 0), (0, 30))[0] < 0
    small = derive_road_edges(RoadMap((lane(1, (0, 0), (6, 0), (6, 6), (0, 6), (0, 0)),)))
    assert len(small) == 1  # a 2.4 m square hole is a gap between lanes, not an island
    assert signed(small, (3, 3))[0] < 0


def test_a_map_with_road_edges_is_left_alone():
    toy = make_scenario()
    assert derive_road_edges(toy.road_map) == ()
    measured = measured_road_edges(toy)
    assert len(measured) == 2 and all(a is b for a, b in zip(measured, toy.road_map.road_edges, strict=True))
    assert with_derived_road_edges(toy) is toy and road_edges_derived_from(toy) == ""


def test_a_map_without_lanes_gets_no_edges_and_stays_unmeasured():
    crosswalk = MapFeature(1, MapFeatureType.CROSSWALK, [[0, 0, 0], [4, 0, 0], [4, 6, 0], [0, 6, 0]])
    bare = with_map(crosswalk)
    assert derive_road_edges(bare.road_map) == () and measured_road_edges(bare) == []
    assert SceneMap.from_scenario(bare).road_edges is None
    assert with_derived_road_edges(bare) is bare


def test_the_switch_turns_the_derivation_off(monkeypatch):
    lanes_only = with_map(lane(1, (-60, 0), (160, 0)))
    monkeypatch.setenv(SWITCH, "0")
    assert measured_road_edges(lanes_only) == [] and SceneMap.from_scenario(lanes_only).road_edges is None
    assert len(measured_road_edges(lanes_only, derive=True)) == 1
    monkeypatch.setenv(SWITCH, "maybe")
    with pytest.raises(InputError, match=f"{SWITCH}: must be 1 or 0, got 'maybe'"):
        measured_road_edges(lanes_only)


def test_metrics_and_guidance_measure_one_road():
    from langtraj.guidance.scene import GuidanceScene

    lanes_only = with_map(lane(1, (-60, 0), (160, 0)), lane(2, (-60, 3.5), (160, 3.5)))
    edges = measured_road_edges(lanes_only)
    assert edges[0] is measured_road_edges(lanes_only)[0]  # derived once per road map
    assert road_edges_derived_from(lanes_only) == FROM_LANES
    drawn = with_derived_road_edges(lanes_only)
    assert [f.id for f in drawn.road_map.road_edges] == [3]
    assert drawn.road_map.features[:2] == lanes_only.road_map.features
    guide = GuidanceScene.from_scenario(lanes_only, (0.0, 0.0, 0.0), [0])
    ring = edges[0].points[:, :2]
    np.testing.assert_allclose(guide.road_edges.numpy(), np.stack([ring[:-1], ring[1:]], 1), atol=1e-4)
    assert lanes_only.agents.types[0] == AgentType.VEHICLE  # track 7, driving along lane 1
    assert offroad_rate(lanes_only, generate_baseline("log_replay", lanes_only, 1), [7]) == 0.0
    shifted = generate_baseline("log_replay", lanes_only, 1)
    shifted.y[:] += 8.0
    assert offroad_rate(lanes_only, shifted, [7]) == 1.0


def test_bad_options_are_one_line_errors():
    with pytest.raises(InputError, match="need lane_width > 0"):
        derive_road_edges(RoadMap((lane(1, (0, 0), (10, 0)),)), lane_width=0)


def test_real_nuscenes_scene_logged_vehicles_lie_in_the_derived_area(real_data_dir):
    scene = read_scenario(real_data_dir / NUSCENES_0061, 0)
    assert not scene.road_map.road_edges and len(drivable_outline_ids(scene)) == 29
    edges = measured_road_edges(scene)
    assert edges and {f.derived_from for f in edges} == {FROM_LANES_AND_OUTLINE}
    lanes_only = derive_road_edges(scene.road_map)
    vehicles = scene.agents.types == AgentType.VEHICLE
    now = scene.current_index
    for derived in (edges, lanes_only):
        index = road_edge_index([f.points for f in derived])
        at_now = scene.agents.xy[vehicles & scene.agents.valid[:, now], now].astype(np.float64)
        assert len(at_now) == 17
        assert (index.signed_distance(np.c_[at_now, np.zeros(len(at_now))]) < 0).all()  # every one on the road
        logged = scene.agents.xy[vehicles][scene.agents.valid[vehicles]].astype(np.float64)
        inside = index.signed_distance(np.c_[logged, np.zeros(len(logged))]) < 0
        assert inside.mean() > 0.95  # 0.961: the rest are two parked cars on the kerb


def test_real_waymo_scene_keeps_its_own_edges(real_data_dir):
    scene = read_scenario(real_data_dir / "sd_training.tfrecord-00000-of-01000_2a1e44d405a6833f.pkl", 0)
    own = scene.road_map.road_edges
    assert own and all(a is b for a, b in zip(measured_road_edges(scene), own, strict=True))
    assert drivable_outline_ids(scene) == () and road_edges_derived_from(scene) == ""
