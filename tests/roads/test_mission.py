"""The ego's route carries each lane's speed limit (docs/testing.md, 'The route'): per point along a chain of lanes,
NaN where the map gives none, and through the observation as `route_speed_limit` (0 where unknown)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from langtraj.roads import MapIndex
from langtraj.roads.mission import Route, ego_route
from langtraj.roads.position import AgentOnLane
from langtraj.scenario import MapFeature, MapFeatureType, RoadMap
from langtraj.scenario.model import MPH_TO_MPS


def lane(feature_id: int, x0: float, x1: float, mph: float, entry=(), exit=()) -> MapFeature:
    points = np.stack([np.linspace(x0, x1, 21), np.zeros(21), np.zeros(21)], axis=1)
    return MapFeature(
        feature_id, MapFeatureType.LANE_SURFACE_STREET, points, entry_lanes=entry, exit_lanes=exit, speed_limit_mph=mph
    )


@pytest.fixture
def chain() -> MapIndex:
    """Three lanes east along y = 0: 0-100 m at 25 mph, 100-200 m at 45 mph, 200-400 m without a limit."""
    return MapIndex.build(
        RoadMap(
            (
                lane(1, 0.0, 100.0, 25.0, exit=(2,)),
                lane(2, 100.0, 200.0, 45.0, entry=(1,), exit=(3,)),
                lane(3, 200.0, 400.0, math.nan, entry=(2,)),
            )
        )
    )


def test_each_point_has_its_lanes_limit(chain: MapIndex):
    start = AgentOnLane(lane=0, station=30.0, speed=10.0)
    route = ego_route(chain, start, np.array([30.0, 0.0]), 0.0, np.zeros((0, 2)))
    assert route.source == "lanes"
    x = route.points[:, 0]
    assert np.allclose(route.speed_limits[x < 99.0], 25 * MPH_TO_MPS)
    assert np.allclose(route.speed_limits[(x > 101.0) & (x < 199.0)], 45 * MPH_TO_MPS)
    assert np.isnan(route.speed_limits[x > 201.0]).all() and (x > 201.0).any()
    _, valid, limits = route.ahead(route.station(np.array([60.0, 0.0])), 50, 2.0)  # 60 m to 158 m
    assert valid.all() and np.allclose(limits[:19], 25 * MPH_TO_MPS) and np.allclose(limits[-25:], 45 * MPH_TO_MPS)
    _, valid, limits = route.ahead(route.length - 10.0, 50, 2.0)
    assert not valid[-1] and np.isnan(limits[~valid]).all()


def test_a_route_off_the_lanes_has_no_limits():
    route = Route.of(np.stack([np.arange(10.0), np.zeros(10)], axis=1), "heading")
    assert np.isnan(route.speed_limits).all() and len(route.speed_limits) == len(route.points)


def test_a_map_that_links_no_lanes_is_linked_by_geometry():
    """Lanes end to start, headings agreeing (nuScenes maps as ScenarioNet converts them link none): a route goes on
    through them; a lane starting 3 m off the end, or turned back, is no exit."""
    lanes = (
        lane(1, 0.0, 100.0, 25.0),
        lane(2, 100.5, 200.0, 25.0),  # starts 0.5 m past lane 1's end
        lane(3, 103.0, 150.0, 25.0),  # 3 m past it: not linked
        lane(4, 100.0, 50.0, 25.0),  # heading back west: not linked
    )
    index = MapIndex.build(RoadMap(lanes))
    assert index.connectivity_source == "geometry" and index.exits[0] == (1,) and index.entries[1] == (0,)
    linked = MapIndex.build(RoadMap((lane(1, 0.0, 100.0, 25.0, exit=(3,)), *lanes[1:])))
    assert linked.connectivity_source == "map" and linked.exits[0] == (2,)  # the map's own links, kept as they are


def test_nuscenes_routes_cover_the_logged_drive(real_data_dir):
    """The ego's route on each shared nuScenes scene reaches past where the logged ego went and stays near it."""
    from langtraj.env import LangTrajEnv
    from langtraj.polylines import project_on_polyline

    for path in sorted(real_data_dir.glob("sd_nuscenes_*.pkl")):
        env = LangTrajEnv(path, policy="log_replay")
        _, info = env.reset(seed=0)
        logged = info["logged_ego"][np.isfinite(info["logged_ego"][:, 0]), :2]
        drive = float(np.hypot(*np.diff(logged, axis=0).T).sum()) if len(logged) > 1 else 0.0
        assert info["route_length_m"] >= drive + 20.0, path.name
        if drive > 5.0:
            on = project_on_polyline(logged, env._route.points)
            assert info["route_source"] == "log" and on.distance.mean() < 2.0, path.name
