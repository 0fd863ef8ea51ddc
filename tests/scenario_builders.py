"""Small scenarios built in memory for tests (no files needed)."""

from __future__ import annotations

import numpy as np

from langtraj.scenario import (
    Agents,
    AgentType,
    BehaviorEvent,
    LaneNeighbor,
    MapFeature,
    MapFeatureType,
    RoadMap,
    Scenario,
    TrafficLights,
)


def make_scenario(
    num_agents: int = 4,
    num_steps: int = 91,
    *,
    scenario_id: str = "toy",
    seed: int = 0,
    with_events: bool = True,
) -> Scenario:
    """A small synthetic scene: agents driving east at different speeds, a lane pair, road lines and
    edges, a crosswalk, a stop sign and one traffic light cycling red -> green."""
    rng = np.random.default_rng(seed)
    t = np.arange(num_steps) * 0.1
    states = np.zeros((num_agents, num_steps, 9), np.float32)
    for a in range(num_agents):
        speed = 2.0 + 3.0 * a
        states[a, :, 0] = -20.0 + 8.0 * a + speed * t
        states[a, :, 1] = 3.5 * (a % 2) + rng.normal(0, 0.01, num_steps)
        states[a, :, 2] = 0.5
        states[a, :, 3] = 0.0
        states[a, :, 4] = speed
        states[a, :, 6:9] = (4.5, 2.0, 1.6)
    valid = np.ones((num_agents, num_steps), bool)
    if num_agents > 2:
        valid[2, : num_steps // 3] = False  # appears late
    types = [AgentType.VEHICLE, AgentType.PEDESTRIAN, AgentType.CYCLIST, AgentType.OTHER] * num_agents
    lane_pts = np.stack([np.linspace(-50, 150, 41), np.zeros(41), np.zeros(41)], axis=1)
    features = (
        MapFeature(
            100,
            MapFeatureType.LANE_SURFACE_STREET,
            lane_pts,
            exit_lanes=(101,),
            speed_limit_mph=25.0,
            left_neighbors=(LaneNeighbor(101, 0, 40, 0, 40),),
        ),
        MapFeature(101, MapFeatureType.LANE_SURFACE_STREET, lane_pts + [0, 3.5, 0], entry_lanes=(100,)),
        MapFeature(200, MapFeatureType.ROAD_LINE_BROKEN_SINGLE_WHITE, lane_pts + [0, 1.75, 0]),
        MapFeature(300, MapFeatureType.ROAD_EDGE_BOUNDARY, lane_pts + [0, -1.75, 0]),
        MapFeature(301, MapFeatureType.ROAD_EDGE_BOUNDARY, (lane_pts + [0, 5.25, 0])[::-1]),  # road on its left
        MapFeature(400, MapFeatureType.CROSSWALK, [[40, -1.75, 0], [44, -1.75, 0], [44, 5.25, 0], [40, 5.25, 0]]),
        MapFeature(500, MapFeatureType.STOP_SIGN, [[38, -2.5, 0]], controlled_lanes=(100,)),
    )
    light_states = np.where(np.arange(num_steps) < num_steps // 2, 4, 6).astype(np.int8)[:, None]
    lights = TrafficLights([100], light_states, np.ones((num_steps, 1), bool), [[38.0, 0.0, 0.0]])
    events = (
        (BehaviorEvent("lane_change", 17, 20, 45, 7, {"direction": "left", "reason": "speedGain"}),)
        if with_events and num_agents > 1
        else ()
    )
    return Scenario(
        scenario_id=scenario_id,
        timestamps=t,
        current_index=min(10, num_steps - 1),
        sdc_index=0,
        agents=Agents(
            ids=np.arange(num_agents) * 10 + 7,
            types=np.array(types[:num_agents], np.int8),
            states=states,
            valid=valid,
            tracks_to_predict=[1] if num_agents > 1 else [],
            prediction_difficulty=[1] if num_agents > 1 else [],
            objects_of_interest=[0, 1] if num_agents > 1 else [],
        ),
        road_map=RoadMap(features),
        traffic_lights=lights,
        events=events,
        metadata={"origin": "test"},
    )


def two_lane_road(starts, *, scenario_id: str = "straight", steps: int = 91) -> Scenario:
    """A 500 m straight road, two lanes eastbound (centres y = 0 and 3.5, edges at -1.75 and 5.25), with a 4.5 m by
    2 m car per (x, y, speed) of `starts`, at (x, y) at the current step (index 10) and keeping its speed for
    `steps` steps; the first is the self-driving car."""
    t = np.arange(steps) * 0.1
    states = np.zeros((len(starts), steps, 9), np.float32)
    for a, (x0, y0, speed) in enumerate(starts):
        states[a, :, 0] = x0 - 1.0 * speed + speed * t
        states[a, :, 1] = y0
        states[a, :, 4] = speed
        states[a, :, 6:9] = (4.5, 2.0, 1.6)
    lane = np.stack([np.linspace(-200, 300, 101), np.zeros(101), np.zeros(101)], axis=1)
    features = (
        MapFeature(10, MapFeatureType.LANE_SURFACE_STREET, lane, left_neighbors=(LaneNeighbor(11, 0, 100, 0, 100),)),
        MapFeature(
            11,
            MapFeatureType.LANE_SURFACE_STREET,
            lane + [0, 3.5, 0],
            right_neighbors=(LaneNeighbor(10, 0, 100, 0, 100),),
        ),
        MapFeature(20, MapFeatureType.ROAD_LINE_BROKEN_SINGLE_WHITE, lane + [0, 1.75, 0]),
        MapFeature(30, MapFeatureType.ROAD_EDGE_BOUNDARY, lane + [0, -1.75, 0]),
        MapFeature(31, MapFeatureType.ROAD_EDGE_BOUNDARY, (lane + [0, 5.25, 0])[::-1]),
    )
    return Scenario(
        scenario_id=scenario_id,
        timestamps=t,
        current_index=10,
        sdc_index=0,
        agents=Agents(
            ids=np.arange(1, len(starts) + 1),
            types=np.full(len(starts), int(AgentType.VEHICLE), np.int8),
            states=states,
            valid=np.ones((len(starts), steps), bool),
            tracks_to_predict=[1],
            prediction_difficulty=[1],
            objects_of_interest=[],
        ),
        road_map=RoadMap(features),
        metadata={"origin": "test"},
    )
