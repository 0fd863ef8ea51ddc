"""Right of way in fault (`env.fault.right_of_way`, `env.right_of_way`, docs/testing.md, 'Step info'): at a junction,
a car that ran its red light or passed a stop sign owes the way to one that did not; failing those, a car turning
across the road the ego keeps, or one coming off the road, owes the ego the way, and the ego turning across a road
owes it to the road's traffic."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from interdrive.test_counterfactual import LEFT_TURN, four_way

from langtraj.env.events import EventJudge
from langtraj.env.fault import CollisionKind, at_fault, collision_kind, gives_way, right_of_way
from langtraj.env.right_of_way import ENTRY_MEMORY_S, Basis, RightOfWay
from langtraj.env.rules import EpisodeLights
from langtraj.metrics.interaction import pair_signed_distance
from langtraj.roads import MapIndex
from langtraj.scenario import Agents, AgentType, MapFeature, MapFeatureType, RoadMap, Scenario, TrafficLights
from langtraj.scenario.types import StateField, TrafficLightState

INDEX = MapIndex.build(four_way())  # junction lanes: 42 eastbound straight (y = -1.75), 11 a left turn north to west
HALF = 1.75


def _box(x: float, y: float, heading: float, speed: float) -> np.ndarray:
    return np.array([x, y, heading, 4.5, 2.0, speed * math.cos(heading), speed * math.sin(heading)])


def _kind(ego: np.ndarray, other: np.ndarray, passed: RightOfWay | None = None) -> CollisionKind:
    return collision_kind(ego, other, INDEX, right_of_way(INDEX, ego, other, passed))


def _first_contact(mover, other: np.ndarray, start: float) -> np.ndarray:
    """`mover(s)` (a box along its way at s) at the first s from `start` on, every 5 cm, whose box touches `other`."""

    def gap(s: float) -> float:
        return float(pair_signed_distance(*(np.array(v) for v in mover(s)[:5]), *(np.array(v) for v in other[:5])))

    s = start
    while s < start + 40.0 and gap(s) >= 0:
        s += 0.05
    return mover(s)


def _turning_car() -> np.ndarray:
    k = int(np.argmin(np.abs(LEFT_TURN[:, 1] + 1.75)))  # where the left turn crosses the eastbound lane
    d = LEFT_TURN[k + 1] - LEFT_TURN[k - 1]
    return _box(*LEFT_TURN[k, :2], math.atan2(d[1], d[0]), 5.0)


def test_a_car_turning_across_the_road_the_ego_keeps_is_not_the_egos_fault():
    turning = _turning_car()
    ego = _first_contact(lambda s: _box(-20.0 + s, -1.75, 0.0, 8.0), turning, 0.0)  # straight on, eastbound
    kind = _kind(ego, turning)
    assert kind is CollisionKind.CROSSED and not at_fault(kind, left_lane=False)
    assert at_fault(kind, left_lane=True)  # unless the ego had left its lane


def test_the_ego_turning_across_a_road_owes_the_way_and_a_straight_crossing_stays_its_own():
    turning_ego = _turning_car()
    through = _box(-8.0, -1.75, 0.0, 8.0)  # eastbound on lane 42
    assert gives_way(INDEX, keeper=through, crosser=turning_ego)  # the turning car gives way to the through one
    assert not gives_way(INDEX, keeper=turning_ego, crosser=through)
    hit_in_its_side = _first_contact(lambda s: _box(-20.0 + s, -1.75, 0.0, 8.0), turning_ego, 0.0)
    kind = _kind(turning_ego, hit_in_its_side)  # the through car's front meets the turning ego's side
    assert kind is CollisionKind.OWED and at_fault(kind, left_lane=False)
    assert right_of_way(INDEX, turning_ego, hit_in_its_side) == RightOfWay(ego_owed=True, basis=Basis.LANES)
    crossing = _box(-1.75, -1.75, 0.0, 8.0)  # eastbound on lane 42, straight across the northbound lane
    ego = _first_contact(lambda s: _box(-1.75, -12.0 + s, math.pi / 2, 8.0), crossing, 0.0)  # straight on, lane 12
    assert _kind(ego, crossing) is CollisionKind.FRONT  # neither signal, sign nor turn: the ego's to avoid


def test_a_car_coming_off_the_road_is_not_the_egos_fault():
    from_driveway = _box(-36.5, -4.5, math.pi / 2, 3.0)  # its centre 2.75 m south of lane 41, across it: no lane
    ego = _first_contact(lambda s: _box(-50.0 + s, -1.75, 0.0, 8.0), from_driveway, 0.0)
    ego[0] += 0.5  # half a metre into it: its bumper on the other's side
    kind = _kind(ego, from_driveway)  # coming across from off its lane: the cut-in rule's side contact
    assert kind is CollisionKind.LATERAL and not at_fault(kind, left_lane=False)
    assert gives_way(INDEX, keeper=ego, crosser=from_driveway)  # and it owed the ego the right of way


# ------------------------------------------------------------------ signals and signs, over an episode's steps

STEPS, NOW = 91, 10
EGO_LANE, CROSS_LANE = 12, 42  # the junction lanes the ego (north, x = -1.75) and the other (east, y = -1.75) take
EGO_LEFT_TURN = 11  # the other junction lane from the ego's approach, starting where 12 does


def _crossing_scene(ego_lead_m: float, *, red: str | None = None, signs: tuple[int, ...] = (), types=None):
    """The four-way junction: the ego (row 0) northbound on lane 2 and the other (row 1) eastbound on lane 41, both
    at 8 m/s and 20 m from the crossing point (-1.75, -1.75) at the scene's current step, the ego `ego_lead_m`
    nearer; `red`: whose junction lane ("ego" or "other") shows a red light all along (the other a green one), at
    its start as WOMD's stop points; `signs`: the junction lanes a stop sign beside their start controls (as WOMD's
    signs mostly name the lanes that start at their line)."""
    t = (np.arange(STEPS) - NOW) * 0.1
    states = np.zeros((2, STEPS, 9), np.float32)
    states[0, :, StateField.X], states[0, :, StateField.Y] = -HALF, -HALF - 20.0 + ego_lead_m + 8.0 * t
    states[0, :, StateField.HEADING], states[0, :, StateField.VY] = math.pi / 2, 8.0
    states[1, :, StateField.X], states[1, :, StateField.Y] = -HALF - 20.0 + 8.0 * t, -HALF
    states[1, :, StateField.VX] = 8.0
    states[:, :, 6:9] = (4.5, 2.0, 1.6)
    features = list(four_way())
    for k, lane in enumerate(signs):
        first, second = next(f for f in features if f.id == lane).points[:2]
        heading = math.atan2(second[1] - first[1], second[0] - first[0])
        kerb = first + 3.0 * np.array([math.sin(heading), -math.cos(heading), 0.0])  # 3 m to the lane's right
        features.append(MapFeature(900 + k, MapFeatureType.STOP_SIGN, kerb[None], controlled_lanes=(lane,)))
    lights = None
    if red is not None:
        ego_way, other_way = (EGO_LANE, EGO_LEFT_TURN), (CROSS_LANE,)  # one stop point for the ego's two ways
        lanes = ego_way + other_way if red == "ego" else other_way + ego_way
        stops = [next(f for f in features if f.id == lane).points[0] for lane in lanes]
        reds = len(ego_way if red == "ego" else other_way)
        row = [int(TrafficLightState.STOP)] * reds + [int(TrafficLightState.GO)] * (len(lanes) - reds)
        light = np.array([row] * STEPS, np.int8)
        lights = TrafficLights(np.array(lanes), light, np.ones_like(light, bool), np.array(stops))
    scenario = Scenario(
        scenario_id="crossing",
        timestamps=np.arange(STEPS) * 0.1,
        current_index=NOW,
        sdc_index=0,
        agents=Agents(
            ids=np.array([1, 2]),
            types=np.array(types or [int(AgentType.VEHICLE)] * 2, np.int8),
            states=states,
            valid=np.ones((2, STEPS), bool),
            tracks_to_predict=[1],
            prediction_difficulty=[1],
            objects_of_interest=[],
        ),
        road_map=RoadMap(tuple(features)),
        metadata={"origin": "test"},
    )
    return scenario if lights is None else replace(scenario, traffic_lights=lights)


def _first_contact_in_episode(scenario: Scenario, lights: str = "log"):
    """The first contact of the ego with the log's steps judged one by one from the scene's current step."""
    judge = EventJudge(scenario, 0, None, MapIndex.build(scenario.road_map), EpisodeLights(scenario, lights))
    for step in range(scenario.current_index + 1, STEPS):
        events = judge.judge(scenario.agents.states[:, step], np.ones(2, bool), step)
        if events.contacts:
            return events.contacts[0]
    raise AssertionError("no contact")


@pytest.mark.parametrize("lead", [2.0, -2.0])  # the ego's side hit, or its bumper into the other's side
def test_a_red_light_decides_a_straight_crossing(lead):
    runner_hit = _first_contact_in_episode(_crossing_scene(lead, red="other"))
    assert runner_hit.kind in (CollisionKind.CROSSED, CollisionKind.LATERAL) and not runner_hit.at_fault
    ego_ran = _first_contact_in_episode(_crossing_scene(lead, red="ego"))
    assert (ego_ran.kind, ego_ran.at_fault, ego_ran.right_of_way) == (CollisionKind.OWED, True, "signal")
    if lead < 0:  # the ego's front into the runner: without the light, the ego's own front collision
        assert runner_hit.to_json() == {"with": 2, "kind": "crossed", "at_fault": False, "right_of_way": "signal"}
        assert _first_contact_in_episode(_crossing_scene(lead)).kind is CollisionKind.FRONT


def test_a_stop_sign_decides_a_straight_crossing_and_at_an_all_way_stop_the_later_owes():
    other_had_sign = _first_contact_in_episode(_crossing_scene(-2.0, signs=(CROSS_LANE,)))
    assert (other_had_sign.kind, other_had_sign.at_fault, other_had_sign.right_of_way) == ("crossed", False, "sign")
    ego_had_sign = _first_contact_in_episode(_crossing_scene(2.0, signs=(EGO_LANE,)))
    assert (ego_had_sign.kind, ego_had_sign.at_fault, ego_had_sign.right_of_way) == ("owed", True, "sign")
    ego_first = _first_contact_in_episode(_crossing_scene(2.0, signs=(EGO_LANE, CROSS_LANE)))  # passed its sign first
    assert ego_first.kind in ("lateral", "crossed") and not ego_first.at_fault
    ego_later = _first_contact_in_episode(_crossing_scene(-2.0, signs=(EGO_LANE, CROSS_LANE)))
    assert (ego_later.kind, ego_later.at_fault) == ("owed", True)


def test_a_red_run_before_the_start_counts_and_held_lights_are_those_at_the_start():
    lead = -2.0
    scenario = _crossing_scene(lead, red="other")
    late = replace(scenario, current_index=22)  # the other crossed its red line (x = -10) at about step 21
    assert _first_contact_in_episode(late).right_of_way == "signal"
    turns_red = scenario.traffic_lights.states.copy()
    turns_red[:15] = int(TrafficLightState.GO)
    turns_red[:15, 1:] = int(TrafficLightState.STOP)  # the ego's lights red and the other's green until step 15
    changed = replace(scenario, traffic_lights=replace(scenario.traffic_lights, states=turns_red))
    assert _first_contact_in_episode(changed, "log").right_of_way == "signal"
    assert _first_contact_in_episode(changed, "held").kind is CollisionKind.OWED  # held: the ego's red at the start


def test_a_pedestrian_or_cyclist_crossing_in_front_stays_the_egos_to_avoid():
    scene = _crossing_scene(-2.0, signs=(CROSS_LANE,), types=[int(AgentType.VEHICLE), int(AgentType.CYCLIST)])
    hit = _first_contact_in_episode(scene)
    assert (hit.kind, hit.at_fault, hit.right_of_way) == ("front", True, None)


def test_a_passing_is_forgotten_once_the_junction_is_cleared():
    scenario = _crossing_scene(-2.0, red="other")
    judge = EventJudge(scenario, 0, None, MapIndex.build(scenario.road_map), EpisodeLights(scenario))
    assert judge.passings is not None
    for step in range(NOW + 1, 40):
        judge.judge(scenario.agents.states[:, step], np.ones(2, bool), step)
    crossed_at = int(judge.passings.red[1])
    assert NOW < crossed_at < 40 and judge.passings.red[0] < 0  # the other crossed its red line, the ego none
    memory = round(ENTRY_MEMORY_S / 0.1)  # steps
    assert judge.passings.right_of_way(0, 1, crossed_at + memory) == RightOfWay(ego_owed=False, basis=Basis.SIGNAL)
    assert judge.passings.right_of_way(0, 1, crossed_at + memory + 1) is None
    with pytest.raises(ValueError, match="in order"):
        judge.judge(scenario.agents.states[:, 20], np.ones(2, bool), 20)
