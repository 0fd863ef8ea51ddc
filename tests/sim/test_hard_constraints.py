"""A LangTraj simulation's hard constraints and held parked cars, end to end with the shipped checkpoint on a
constructed straight road: a car guided off the road stays on it with the projection, and a car parked at the kerb
stands still while the others drive."""

from __future__ import annotations

import numpy as np
import pytest

from langtraj.guidance import GuidanceTerm
from langtraj.guidance.costs import GoalCost
from langtraj.guidance.projection import HardConstraints
from langtraj.metrics.features import SceneMap
from langtraj.metrics.road import distance_to_road_edge
from langtraj.model.checkpoint import load_model
from langtraj.scenario import Agents, AgentType, LaneNeighbor, MapFeature, MapFeatureType, RoadMap, Scenario
from langtraj.sim.checkpoints import shipped_checkpoint
from langtraj.sim.config import SimConfig, SimRequest
from langtraj.sim.engine import simulate
from langtraj.sim.parked import parked_in_history
from langtraj.sim.policies import LangTrajPolicy, hard_constraints

PARKED_ID = 4


def straight_road(parked: bool = True) -> Scenario:
    """A 500 m straight road, two lanes eastbound (y = 0 and 3.5, edges at -1.75 and 5.25): three cars at 10 m/s and,
    with `parked`, a fourth standing at the kerb (y = -0.7) all through the log."""
    steps, length, width = 91, 4.5, 2.0
    t = np.arange(steps) * 0.1
    starts = [(0.0, 0.0, 10.0), (-25.0, 0.0, 10.0), (-10.0, 3.5, 10.0)] + ([(40.0, -0.7, 0.0)] if parked else [])
    states = np.zeros((len(starts), steps, 9), np.float32)
    for a, (x0, y0, speed) in enumerate(starts):
        states[a, :, 0] = x0 - 1.0 * speed + speed * t
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
        scenario_id="straight",
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


@pytest.fixture(scope="module")
def shipped():
    return load_model(shipped_checkpoint())


def worst_offroad(scenario: Scenario, result, agent: int) -> float:
    """The largest box-corner distance past the road edge (m, WOSAC's geometry) of `agent` over every rollout."""
    edges = SceneMap.from_scenario(scenario).road_edges
    track = result.world.states[:, agent, scenario.current_index + 1 :]  # [R, T, StateField]
    ones = np.ones(track.shape[:2])
    x, y, heading = track[..., 0], track[..., 1], track[..., 3]
    return float(distance_to_road_edge(edges, x, y, 0 * ones, heading, 4.5 * ones, 2.0 * ones, ones, ones > 0).max())


def test_a_car_guided_off_the_road_stays_on_it_with_the_hard_constraints(shipped):
    scenario = straight_road(parked=False)
    model, data = shipped
    off_road = (GuidanceTerm(GoalCost(0, (60.0, -8.0)), weight=20.0),)  # pulls the first car off the road
    runs = {}
    for name, constraints in (("free", None), ("projected", HardConstraints())):
        policy = LangTrajPolicy(model, data, terms=off_road, hard_constraints=constraints)
        runs[name] = worst_offroad(scenario, simulate(scenario, policy, SimConfig(rollouts=2, seed=0)), 0)
    assert runs["free"] > 0.5  # the guidance drives its box half a metre and more past the edge ...
    assert runs["projected"] < 0.0  # ... and the projection keeps all of it on the road


def test_a_parked_car_stands_still_when_held(shipped):
    scenario = straight_road()
    parked = parked_in_history(scenario)
    assert parked.tolist() == [False, False, False, True]
    model, data = shipped
    result = simulate(scenario, LangTrajPolicy(model, data, hold_parked=True), SimConfig(rollouts=2, seed=0))
    track = result.world.states[:, 3, scenario.current_index :]
    assert np.allclose(track[..., :2], track[:, :1, :2], atol=1e-4)
    assert np.all(track[:, 1:, 4:6] == 0)  # no velocity
    # A prompt that names it lets the model drive it.
    policy = LangTrajPolicy.from_request(scenario, SimRequest(prompts=(f"@{PARKED_ID} speeds up",), hold_parked=True))
    assert policy.held_slots(scenario, result.world, ()) == ()


def test_requests_turn_the_projection_off_or_on_at_a_number_of_steps():
    assert hard_constraints(0, 5) is None
    assert hard_constraints(2, 5) == HardConstraints(steps=2)
    with pytest.raises(Exception, match="--hard-constraints"):
        hard_constraints(6, 5)
