"""What a scene can stage (`interdrive.suggest`): on a two-lane road built here, each staging the map allows is listed
once per feasible parameter value, with a prompt that reads back as it, most natural first; agents out of reach or of
the wrong kind are not asked; and on every shared real scene every listed staging is feasible."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scenario_builders import two_lane_road

from langtraj.errors import InputError
from langtraj.interdrive.behaviour import Behaviour
from langtraj.interdrive.behaviours import kind
from langtraj.interdrive.reader import read_prompt
from langtraj.interdrive.suggest import (
    Staging,
    count_by_behaviour,
    ego_of,
    pair_behaviours,
    parse_behaviour,
    prompt_text,
    suggest_stagings,
)
from langtraj.interdrive.targets import feasibility
from langtraj.roads import MapIndex
from langtraj.roads.mission import mission_of
from langtraj.scenario import AgentType
from langtraj.scenario.io import read_scenarios

STARTS = [
    (0.0, 0.0, 10.0),  # 1: the ego, right lane
    (0.0, 3.5, 10.0),  # 2: level with it in the left lane: a cut-in
    (25.0, 0.0, 10.0),  # 3: its lead, 20.5 m ahead: a braking lead
    (-15.0, 0.0, 10.0),  # 4: behind it, 10.5 m: a tailgater, a follower
    (150.0, 0.0, 10.0),  # 5: beyond every radius
    (-8.0, 3.5, 10.0),  # 6: a pedestrian (made one below): never asked
]


def _road():
    s = two_lane_road(STARTS)
    types = s.agents.types.copy()
    types[5] = int(AgentType.PEDESTRIAN)
    return replace(s, agents=replace(s.agents, types=types))


def _verdict(s, staging: Staging, index: MapIndex):
    """The staging asked alone, the ego on the route its planner is given (as the env stages it)."""
    mission = mission_of(s, s.agents.index_of(staging.other), index)
    return feasibility(
        s,
        staging.agent,
        staging.behaviour,
        index,
        other_id=staging.other,
        gap=staging.parameters.get("gap"),
        deceleration=staging.parameters.get("deceleration"),
        routes={staging.other: mission.points},
    )


def _assert_feasible_and_read_back(s, stagings, index: MapIndex) -> None:
    """Each staging is feasible when asked alone (a fresh read of the map, where the search shares one across
    agents), reads back as staged, and the list is sorted."""
    for staging in stagings:
        assert _verdict(s, staging, index).status == "feasible", staging
        reading = read_prompt(staging.typed_prompt)
        assert (reading.behaviour, reading.agent, reading.other) == (staging.behaviour, staging.agent, staging.other)
        assert reading.metres == staging.parameters.get("gap"), staging.prompt
        assert reading.deceleration == staging.parameters.get("deceleration"), staging.prompt
    scores = [s.score for s in stagings]
    assert scores == sorted(scores)


def test_every_staging_the_two_lane_road_allows_is_listed_once_per_feasible_parameter_most_natural_first():
    s = _road()
    index = MapIndex.build(s.road_map)
    stagings = suggest_stagings(s, map_index=index, scene="road.tfrecord")
    found = {(x.agent, x.behaviour, tuple(x.parameters.values())) for x in stagings}
    assert len(found) == len(stagings)  # no staging twice
    assert {(2, Behaviour.CUT_IN, (g,)) for g in (5.0, 10.0)} <= found
    assert (2, Behaviour.CUT_IN, (15.0,)) not in found  # 3, 20.5 m ahead of the ego, leaves no room for 15 m and a car
    assert {(3, Behaviour.BRAKE_HARD, (d,)) for d in (4.0, 6.0)} <= found
    assert {(4, Behaviour.TAILGATE, ()), (4, Behaviour.FOLLOW, ())} <= found
    assert (3, Behaviour.FOLLOW, ()) not in found  # ahead of the ego: it does not follow it
    assert not {x.agent for x in stagings} & {5, 6}  # out of reach; a pedestrian
    assert all(x.other == 1 and x.scene == "road.tfrecord" and "@ego" in x.prompt for x in stagings)
    _assert_feasible_and_read_back(s, stagings, index)
    brake = [x for x in stagings if x.behaviour is Behaviour.BRAKE_HARD]
    assert [x.prompt for x in brake] == [
        "@3 brakes hard at 4 m/s^2 in front of @ego",
        "@3 brakes hard at 6 m/s^2 in front of @ego",
    ]
    assert [x.default for x in brake] == [True, False]
    cut_in = {x.parameters["gap"]: x for x in stagings if x.behaviour is Behaviour.CUT_IN}
    assert cut_in[10.0].prompt == "@2 cuts in front of @ego with a 10 m gap" and cut_in[10.0].default
    # the closest needed speed to its own 10 m/s first: the 5 m gap (12.4 m/s) before 10 m (13.6)
    assert cut_in[5.0].score < cut_in[10.0].score
    assert cut_in[5.0].change == pytest.approx((5.0 + 4.5) / 4.0, abs=0.01)  # 4 s to gain the gap and lengths
    counts = count_by_behaviour(stagings)
    assert list(counts) == [b.value for b in pair_behaviours()] and sum(counts.values()) == len(stagings)


def test_the_default_parameters_are_those_feasibility_takes_without_one():
    s = _road()
    index = MapIndex.build(s.road_map)
    for behaviour, agent in ((Behaviour.CUT_IN, 2), (Behaviour.OVERTAKE_CUT_IN, 2), (Behaviour.BRAKE_HARD, 3)):
        parameter = kind(behaviour).parameters[0]
        given = {parameter.name: parameter.default}
        plain = feasibility(s, agent, behaviour, index, other_id=1)
        explicit = feasibility(s, agent, behaviour, index, other_id=1, **given)
        assert plain.status == explicit.status == "feasible", behaviour
        assert plain.target.reason == explicit.target.reason


def test_only_the_asked_behaviours_and_another_ego():
    s = _road()
    only = suggest_stagings(s, behaviours=[Behaviour.BRAKE_HARD])
    assert {x.behaviour for x in only} == {Behaviour.BRAKE_HARD}
    as_ego_4 = suggest_stagings(s, ego=4)  # 1 is now 10.5 m ahead of the ego: it may brake hard in front of it
    assert {x.other for x in as_ego_4} == {4} and 4 not in {x.agent for x in as_ego_4}
    assert any(x.agent == 1 and x.behaviour is Behaviour.BRAKE_HARD for x in as_ego_4)
    with pytest.raises(InputError, match="not a behaviour toward another agent"):
        suggest_stagings(s, behaviours=[Behaviour.TURN_LEFT])


def test_behaviour_names_read_loosely_and_unknown_ones_get_a_hint():
    assert parse_behaviour("cut-in") is Behaviour.CUT_IN
    assert parse_behaviour(" Brake hard ") is Behaviour.BRAKE_HARD
    with pytest.raises(InputError, match="did you mean 'cut_in'"):
        parse_behaviour("cut_inn")
    with pytest.raises(InputError, match="'turn_left' is not a behaviour toward another agent"):
        parse_behaviour("turn_left")
    with pytest.raises(InputError, match="unknown behaviour 'honk'; known: go_first, yield, follow, cut_in"):
        parse_behaviour("honk")


def test_the_ego_is_the_self_driving_car_unless_named_and_must_be_in_the_scene_at_the_current_step():
    s = _road()
    assert ego_of(s) == 1 and ego_of(s, 3) == 3
    with pytest.raises(InputError, match="ego: no track 99 in scene straight"):
        ego_of(s, 99)
    with pytest.raises(InputError, match="has no self-driving car"):
        ego_of(replace(s, sdc_index=-1))
    valid = s.agents.valid.copy()
    valid[2, s.current_index] = False
    with pytest.raises(InputError, match="track 3 is not valid at the current step"):
        ego_of(replace(s, agents=replace(s.agents, valid=valid)), 3)


def test_prompts_write_the_parameters_out_and_the_vocabulary_sentence_otherwise():
    assert prompt_text(Behaviour.OVERTAKE_CUT_IN, 7, {"gap": 15.0}) == (
        "@7 overtakes @ego and cuts in front of it with a 15 m gap"
    )
    assert prompt_text(Behaviour.YIELD, 7) == "@7 yields to @ego"
    assert read_prompt("@7 runs the red light across the path of @9").behaviour is Behaviour.RUN_RED_LIGHT
    assert prompt_text(Behaviour.RUN_RED_LIGHT, 7).endswith("@ego")


@pytest.mark.filterwarnings("ignore::langtraj.errors.DataWarning")
def test_every_staging_listed_on_the_real_scenes_is_feasible(real_files: list[Path]):
    for path in real_files:
        s = next(iter(read_scenarios(path)))
        index = MapIndex.build(s.road_map)
        stagings = suggest_stagings(s, map_index=index, scene=str(path))
        assert stagings, f"{path.name}: nothing to stage against the sdc"
        _assert_feasible_and_read_back(s, stagings, index)
        c = s.current_index
        rows = [s.agents.index_of(x.agent) for x in stagings]
        assert s.agents.valid[rows, c].all()
        assert np.isin(s.agents.types[rows], [int(AgentType.VEHICLE), int(AgentType.CYCLIST)]).all()
