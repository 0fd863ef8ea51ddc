"""Scenes built in memory for the environment's tests: a straight two-lane road with an ego and the car that
follows it (no files needed)."""

from __future__ import annotations

import numpy as np

from langtraj.scenario import Agents, AgentType, LaneNeighbor, MapFeature, MapFeatureType, RoadMap, Scenario

EGO_ID, FOLLOWER_ID = 1, 2


def follower_scene(gap_m: float = 12.0, speed: float = 10.0, others: int = 2, steps: int = 91) -> Scenario:
    """A 500 m straight road, two lanes eastbound; the ego (id 1, the self-driving car) at x = 0 in the right lane
    and a follower (id 2) `gap_m` behind it (bumper to bumper), both at `speed`, with `others` cars in the left lane.
    The log has everyone keep their speed for `steps` steps (9.1 s: one window)."""
    t = np.arange(steps) * 0.1
    length, width = 4.5, 2.0
    starts = [(0.0, 0.0), (-(gap_m + length), 0.0)] + [(-30.0 + 25.0 * k, 3.5) for k in range(others)]
    states = np.zeros((len(starts), steps, 9), np.float32)
    for a, (x0, y0) in enumerate(starts):
        states[a, :, 0] = x0 - 1.0 * speed + speed * t  # at x0 at the current step (index 10)
        states[a, :, 1] = y0
        states[a, :, 4] = speed
        states[a, :, 6:9] = (length, width, 1.6)
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
        scenario_id="follower",
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
