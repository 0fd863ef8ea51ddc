"""`sim.parked.parked_in_history`: the labeler's parked rule on the history alone, on a constructed straight road
(two lanes east, road edges on both sides): a car still at the kerb is parked, one that moved or stands on a lane
centre is not, and nothing in the logged future changes the answer. The road builders serve tests/sim/test_failures.py
too."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from langtraj.scenario import (
    FUTURE_STEPS,
    Agents,
    AgentType,
    LaneNeighbor,
    MapFeature,
    MapFeatureType,
    RoadMap,
    Scenario,
)
from langtraj.scenario.types import StateField
from langtraj.sim.parked import parked_in_history

C = 10  # the current step
STEPS = C + 1 + FUTURE_STEPS
CAR = (4.5, 2.0, 1.6)
PERSON = (0.6, 0.6, 1.8)
ROAD_END = 150.0
"""The lanes and road edges run from x = -50 to here."""


def track(start, step=(0.0, 0.0), size=CAR, heading: float = 0.0) -> np.ndarray:
    """States [STEPS, 9] moving by `step` (x, y) per 0.1-s step, at `start` (x, y) at the current step."""
    out = np.zeros((STEPS, 9))
    out[:, :2] = np.asarray(start, float) + (np.arange(STEPS) - C)[:, None] * np.asarray(step, float)
    out[:, StateField.Z] = size[2] / 2
    out[:, StateField.HEADING] = heading
    out[:, StateField.VX : StateField.VY + 1] = np.asarray(step, float) * 10
    out[:, StateField.LENGTH :] = size
    return out


def line(y: float, reverse: bool = False) -> np.ndarray:
    xs = np.linspace(-50.0, ROAD_END, 41)[:: -1 if reverse else 1]
    return np.stack([xs, np.full(41, y), np.zeros(41)], 1)


def road(*, edges: bool = True, junction: bool = False, lanes: bool = True, extra=()) -> RoadMap:
    """Two lanes east (100 at y = 0, 101 at y = 3.5, neighbours), road edges at y = -1.75 and 5.25 (the road on
    their left); `junction` marks both lanes as junction lanes."""
    features = list(extra)
    if lanes:
        features += [
            MapFeature(100, MapFeatureType.LANE_SURFACE_STREET, line(0.0), interpolating=junction,
                       left_neighbors=(LaneNeighbor(101, 0, 40, 0, 40),)),
            MapFeature(101, MapFeatureType.LANE_SURFACE_STREET, line(3.5), interpolating=junction,
                       right_neighbors=(LaneNeighbor(100, 0, 40, 0, 40),)),
        ]  # fmt: skip
    if edges:
        features += [
            MapFeature(300, MapFeatureType.ROAD_EDGE_BOUNDARY, line(-1.75)),
            MapFeature(301, MapFeatureType.ROAD_EDGE_BOUNDARY, line(5.25, reverse=True)),
        ]
    return RoadMap(tuple(features))


def road_scene(tracks, types=None, road_map: RoadMap | None = None, scenario_id: str = "road") -> Scenario:
    """Agents 1, 2, ... following `tracks` on `road_map` (default `road()`); vehicles unless `types` says so."""
    num = len(tracks)
    return Scenario(
        scenario_id=scenario_id,
        timestamps=np.arange(STEPS) * 0.1,
        current_index=C,
        sdc_index=-1,
        agents=Agents(
            ids=np.arange(num) + 1,
            types=np.full(num, AgentType.VEHICLE, np.int8) if types is None else np.array(types, np.int8),
            states=np.stack(tracks),
            valid=np.ones((num, STEPS), bool),
        ),
        road_map=road() if road_map is None else road_map,
    )


def with_future(scenario: Scenario, agent: int, future: np.ndarray, valid: bool = True) -> Scenario:
    """The scene with agent `agent`'s logged future replaced by the states `future` [FUTURE_STEPS, 9]."""
    states, valid_steps = scenario.agents.states.copy(), scenario.agents.valid.copy()
    states[agent, C + 1 :] = future
    valid_steps[agent, C + 1 :] = valid
    return replace(scenario, agents=replace(scenario.agents, states=states, valid=valid_steps))


KERB = (30.0, -0.6)
"""1.15 m from the right road edge: a car standing here is at the kerb."""


def test_a_car_still_at_the_kerb_is_parked_and_others_are_not():
    scenario = road_scene(
        [
            track(KERB),  # parked at the kerb
            track((0.0, 0.0), (1.0, 0.0)),  # driving
            track((60.0, 0.0)),  # stopped on a lane centre, 1.75 m from the edge: in a traffic lane
            track((80.0, -3.5)),  # off every lane (beside the road)
            track((90.0, -0.6), size=PERSON),  # a pedestrian standing at the kerb
            track((100.0, -0.6), (0.2, 0.0)),  # at the kerb, but it moved 2 m over the history
        ],
        types=[AgentType.VEHICLE] * 4 + [AgentType.PEDESTRIAN, AgentType.VEHICLE],
    )
    assert parked_in_history(scenario).tolist() == [True, False, False, True, False, False]


def test_the_logged_future_is_never_read():
    scenario = road_scene([track(KERB), track((60.0, 0.0)), track((0.0, 0.0), (1.0, 0.0))])
    before = parked_in_history(scenario)
    # The parked car drives off and the stopped one leaves, in the future only; the moving one vanishes.
    drives_off = track(KERB, (1.5, 0.3))[C + 1 :]
    changed = with_future(with_future(scenario, 0, drives_off), 1, track((60.0, 0.0), (2.0, 0.0))[C + 1 :])
    changed = with_future(changed, 2, np.zeros((FUTURE_STEPS, 9)), valid=False)
    assert before.tolist() == [True, False, False]
    np.testing.assert_array_equal(parked_in_history(changed), before)


def test_a_car_seen_at_one_step_only_is_judged_by_its_logged_speed():
    scenario = road_scene([track(KERB), track((40.0, -0.6), (1.0, 0.0))])
    valid = scenario.agents.valid.copy()
    valid[:, :C] = False  # both appear at the current step
    scenario = replace(scenario, agents=replace(scenario.agents, valid=valid))
    assert parked_in_history(scenario).tolist() == [True, False]


def test_undecided_maps_count_as_not_parked():
    # Without lanes the road side cannot be told; without road edges the kerb cannot (a car near a lane centre).
    assert not parked_in_history(road_scene([track(KERB)], road_map=road(lanes=False))).any()
    assert not parked_in_history(road_scene([track(KERB)], road_map=road(edges=False))).any()
    # Beside the lane centre needs no kerb.
    assert parked_in_history(road_scene([track((30.0, -2.0))], road_map=road(edges=False))).all()
