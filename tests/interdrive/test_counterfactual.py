"""Counterfactual prompts: behaviour kinds, feasibility from the map on constructed scenes, alternatives, warnings
for infeasible typed prompts, and the hand-written free-text prompts (also the scene builders of
tests/metrics/test_instruction_following.py and tests/cli/test_simulate_prompt_warnings.py)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from roads.test_index import arc, line

from langtraj.errors import InputError
from langtraj.interdrive.adherence import label_facts, lane_change_key, lane_change_side, prompt_facts
from langtraj.interdrive.behaviour import BEHAVIOURS, PAIR_SUBTYPES, Behaviour, behaviour_facts, opposite_subtype
from langtraj.interdrive.counterfactual import feasible_alternatives, logged_facts
from langtraj.interdrive.dataset import PromptEntry
from langtraj.interdrive.free_text import load_free_text_prompts
from langtraj.interdrive.labels import AgentLabel
from langtraj.interdrive.prompts import Prompt, mentions_in, parse_user_prompt
from langtraj.interdrive.prompts.user import recognize_prompt
from langtraj.interdrive.reader import read_prompt
from langtraj.interdrive.targets import CounterfactualConfig, behaviour_feasibility
from langtraj.interdrive.taxonomy import LABELS_BY_KEY, SUBTYPES_BY_ID
from langtraj.roads import MapIndex
from langtraj.scenario import AgentType, LaneNeighbor, MapFeature, MapFeatureType, RoadMap, Scenario

from .test_ground_truth import VEH, straight
from .test_ground_truth import scene as track_scene
from .test_heuristics import TIME, along, scene

FREE_TEXT = Path(__file__).resolve().parents[1] / "data" / "free_text_prompts.yaml"
LANE = MapFeatureType.LANE_SURFACE_STREET
HALF = 1.75  # half a lane width: the two northbound approach lanes run at x = -1.75 (left) and x = +1.75 (right)

# ---------------------------------------------------------------------------------------------- scene builders

LEFT_TURN = arc(-HALF - 11.75, -10, 11.75, 0.0, math.pi / 2)  # from (-1.75, -10) heading north to heading west
RIGHT_TURN = arc(HALF + 8.25, -10, 8.25, math.pi, math.pi / 2)  # from (1.75, -10) heading north to heading east


def four_way(
    connectivity: bool = True, right_lane_exits: tuple[int, ...] = (13, 14), neighbours: bool = True
) -> RoadMap:
    """A junction reached by two northbound lanes: the left lane (2, x = -1.75) allows a left turn (junction lane
    11) and straight on (12) only, the right lane (1, x = +1.75) straight on (13) and a right turn (14) by default
    (`right_lane_exits`); exit lanes 21-24 lead away west, north, north and east, and an eastbound road (41, junction
    lane 42) crosses. Junction lanes are flagged `interpolating`; the approach lanes list each other as neighbours."""
    last = 40

    def links(*ids: int) -> tuple[int, ...]:
        return ids if connectivity else ()

    def nb(feature_id: int) -> tuple[LaneNeighbor, ...]:
        return (LaneNeighbor(feature_id, 0, last, 0, last),) if neighbours else ()

    def from_right(lane: int) -> tuple[int, ...]:  # a junction lane's entry: the right lane, where it leads there
        return links(1) if lane in right_lane_exits else ()

    return RoadMap(
        [
            MapFeature(1, LANE, line(HALF, -80, HALF, -10), exit_lanes=links(*right_lane_exits), left_neighbors=nb(2)),
            MapFeature(2, LANE, line(-HALF, -80, -HALF, -10), exit_lanes=links(11, 12), right_neighbors=nb(1)),
            MapFeature(11, LANE, LEFT_TURN, entry_lanes=links(2), exit_lanes=links(21), interpolating=True),
            MapFeature(12, LANE, line(-HALF, -10, -HALF, 10, 21), entry_lanes=links(2), exit_lanes=links(22),
                       interpolating=True),
            MapFeature(13, LANE, line(HALF, -10, HALF, 10, 21), entry_lanes=from_right(13), exit_lanes=links(23),
                       interpolating=True),
            MapFeature(14, LANE, RIGHT_TURN, entry_lanes=from_right(14), exit_lanes=links(24), interpolating=True),
            MapFeature(21, LANE, line(-13.5, HALF, -80, HALF), entry_lanes=links(11)),
            MapFeature(22, LANE, line(-HALF, 10, -HALF, 80), entry_lanes=links(12)),
            MapFeature(23, LANE, line(HALF, 10, HALF, 80), entry_lanes=links(13)),
            MapFeature(24, LANE, line(10, -HALF, 80, -HALF), entry_lanes=links(14, 42)),
            MapFeature(41, LANE, line(-80, -HALF, -10, -HALF), exit_lanes=links(42)),
            MapFeature(42, LANE, line(-10, -HALF, 10, -HALF, 21), entry_lanes=links(41), exit_lanes=links(24),
                       interpolating=True),
        ]
    )  # fmt: skip


def _approach(x: float) -> np.ndarray:
    return line(x, -80, x, -10)


LEFT_LANE_LEFT = np.concatenate([_approach(-HALF), LEFT_TURN[1:], line(-13.5, HALF, -80, HALF)[1:]])
LEFT_LANE_STRAIGHT = np.concatenate([_approach(-HALF), line(-HALF, -10, -HALF, 80)[1:]])
RIGHT_LANE_RIGHT = np.concatenate([_approach(HALF), RIGHT_TURN[1:], line(10, -HALF, 80, -HALF)[1:]])
RIGHT_LANE_STRAIGHT = np.concatenate([_approach(HALF), line(HALF, -10, HALF, 80)[1:]])


def drive(path: np.ndarray, speed: float = 8.0, start: float = 30.0) -> tuple[AgentType, np.ndarray, np.ndarray]:
    """A car driving along `path` from station `start` at `speed` (at the current step it is 31 m before the
    junction with the defaults)."""
    xy, heading = along(path, start + speed * TIME)
    return AgentType.VEHICLE, xy, heading


def two_lane_road(neighbours: bool = True) -> RoadMap:
    """Two eastbound lanes with no junction: 1 (right, y = 0) and 2 (left, y = 3.5), listed as neighbours."""
    pts = line(-100, 0, 400, 0)
    last = len(pts) - 1

    def nb(feature_id: int) -> tuple[LaneNeighbor, ...]:
        return (LaneNeighbor(feature_id, 0, last, 0, last),) if neighbours else ()

    return RoadMap(
        [
            MapFeature(1, LANE, pts, left_neighbors=nb(2)),
            MapFeature(2, LANE, pts + [0, 3.5], right_neighbors=nb(1)),
        ]
    )


def lane_change(to_y: float, from_y: float = 0.0, speed: float = 10.0) -> tuple[AgentType, np.ndarray, np.ndarray]:
    """An eastbound car moving from y = `from_y` to y = `to_y` between 3 s and 6 s."""
    x = speed * TIME
    blend = np.clip((TIME - 3.0) / 3.0, 0.0, 1.0)
    y = from_y + (to_y - from_y) * (1 - np.cos(np.pi * blend)) / 2
    return AgentType.VEHICLE, np.stack([x, y], axis=1), np.arctan2(np.gradient(y), np.gradient(x))


def x_junction_yield() -> Scenario:
    """Car 1 waits west of a map-less crossing until step 50 while car 2 crosses northbound (at the centre at
    step 40): the detector finds 1 yielding to 2 and 2 passing 1."""
    wait = np.where(np.arange(len(TIME)) < 50, 0.0, 5.0)
    return track_scene({1: (VEH, straight(-8, 0, 0, wait)), 2: (VEH, straight(0, -40, np.pi / 2, 10.0))})


def _entry(text: str, ids=(1, 2)) -> PromptEntry:
    return PromptEntry.of(parse_user_prompt(text, ids))


def _single(alternatives) -> set[Behaviour]:
    return {a.behaviour for a in alternatives if not BEHAVIOURS[a.behaviour].is_pair}


TURNS = {Behaviour.TURN_LEFT, Behaviour.GO_STRAIGHT, Behaviour.TURN_RIGHT}

# ---------------------------------------------------------------------------------------------- behaviour kinds


def test_every_behaviour_has_a_spec_judged_by_taxonomy_facts_and_a_valid_sentence():
    assert set(BEHAVIOURS) == set(Behaviour)
    for behaviour, spec in BEHAVIOURS.items():
        assert spec.behaviour is behaviour
        text = spec.text(5, 9)
        assert parse_user_prompt(text, [5, 9]).mentions == ((5, 9) if spec.is_pair else (5,))
        facts = behaviour_facts(behaviour, 5, 9 if spec.is_pair else None)
        if spec.is_pair:
            ((kind, track, other, subtype),) = facts
            assert (kind, track, other) == ("interaction", 5, 9) and SUBTYPES_BY_ID[subtype].type is spec.interaction
            assert spec.label is None
        else:
            assert {f[:2] for f in facts} == {("label", 5)} and len(facts) == 1 + len(spec.also)
            assert {spec.label, *spec.also} <= set(LABELS_BY_KEY)
            assert ("label", 5, spec.fact_key) in facts
        if spec.is_turn:  # asked at the next intersection: the labeler must see the agent cross one
            assert ("label", 5, "crossing_intersection") in facts
        read = recognize_prompt(Prompt(text, mentions_in(text), source="user"))
        if spec.is_pair:  # the sentence reads back as an interaction of the behaviour's type
            assert SUBTYPES_BY_ID[read.subtype_id].type is spec.interaction
        elif not spec.is_lane_change:  # the template grammar has no undirected "changes lanes to the left"
            assert spec.label in read.label_keys


def test_lane_changes_are_judged_by_their_side():
    assert behaviour_facts(Behaviour.LANE_CHANGE_LEFT, 3) == {("label", 3, "changing_lanes:left")}
    assert lane_change_side({"from": "rightmost", "to": "middle"}) == "left"
    assert lane_change_side({"from": "middle", "to": "rightmost"}) == "right"
    assert lane_change_side({"from": "leftmost", "to": "rightmost"}) == "right"
    assert lane_change_side({"from": "middle", "to": "middle"}) is None
    assert lane_change_side({"from": "single", "to": "leftmost"}) is None
    labels = [AgentLabel(3, "changing_lanes", 20, 40, {"from": "rightmost", "to": "leftmost"})]
    assert label_facts(labels, ()) == {("label", 3, "changing_lanes"), ("label", 3, lane_change_key("left"))}


def test_going_first_and_yielding_are_each_others_opposite():
    for stay, go in PAIR_SUBTYPES:
        assert opposite_subtype(stay, AgentType.VEHICLE) == go
    assert opposite_subtype("passing/intersection_with_yielding", AgentType.VEHICLE) == "yielding/intersection"
    assert opposite_subtype("passing/pedestrian", AgentType.VEHICLE) == "yielding/to_pedestrian"
    assert opposite_subtype("passing/vru_crossing", AgentType.PEDESTRIAN) == "yielding/pedestrian_to_vehicle"
    assert opposite_subtype("passing/vru_crossing", AgentType.CYCLIST) == "yielding/intersection"
    assert opposite_subtype("following/with_lead", AgentType.VEHICLE) is None
    with pytest.raises(InputError, match="needs another agent"):
        behaviour_facts(Behaviour.YIELD, 1)
    with pytest.raises(InputError, match="does not judge"):
        behaviour_facts(Behaviour.YIELD, 1, 2, "passing/pedestrian")


# ---------------------------------------------------------------------------------------------- feasibility


def test_the_alternatives_at_a_junction_are_exactly_the_directions_the_lane_allows():
    s = scene(four_way(), drive(LEFT_LANE_STRAIGHT), drive(RIGHT_LANE_RIGHT))
    index = MapIndex.build(s.road_map)
    left_lane = feasible_alternatives(s, 1, index)
    assert _single(left_lane) & TURNS == {Behaviour.TURN_LEFT, Behaviour.GO_STRAIGHT}
    assert {a.behaviour for a in left_lane if a.logged} >= {Behaviour.GO_STRAIGHT}
    assert not next(a for a in left_lane if a.behaviour is Behaviour.TURN_LEFT).logged
    right_lane = feasible_alternatives(s, 2, index)
    assert _single(right_lane) & TURNS == {Behaviour.GO_STRAIGHT, Behaviour.TURN_RIGHT}
    assert next(a for a in right_lane if a.behaviour is Behaviour.TURN_RIGHT).logged
    # lane changes only into the neighbour that exists
    assert Behaviour.LANE_CHANGE_RIGHT in _single(left_lane) and Behaviour.LANE_CHANGE_LEFT not in _single(left_lane)
    assert Behaviour.LANE_CHANGE_LEFT in _single(right_lane) and Behaviour.LANE_CHANGE_RIGHT not in _single(right_lane)
    verdict = behaviour_feasibility(s, 1, index)[Behaviour.TURN_RIGHT]
    assert verdict.status == "infeasible" and "no right turn from its lane at the next junction" in verdict.reason


def test_an_alternative_is_a_prompt_stating_its_facts():
    s = scene(four_way(), drive(LEFT_LANE_STRAIGHT))
    index = MapIndex.build(s.road_map)
    turn = next(a for a in feasible_alternatives(s, 1, index) if a.behaviour is Behaviour.TURN_LEFT)
    assert turn.prompt.text == "@1 turns left at the next intersection"
    assert turn.prompt.labels == ("turning_left", "crossing_intersection")
    assert turn.prompt.roles[1] == "the target agent turns left at the next intersection"
    assert turn.facts == {("label", 1, "turning_left"), ("label", 1, "crossing_intersection")}
    assert turn.other_id is None and prompt_facts(turn.prompt) == turn.facts  # the entry states what judges it


def test_a_junction_beyond_the_lookahead_offers_no_turn():
    s = scene(four_way(), drive(LEFT_LANE_STRAIGHT, speed=0.0, start=0.0))  # standing 70 m before the junction
    index = MapIndex.build(s.road_map)
    near = behaviour_feasibility(s, 1, index, CounterfactualConfig(lookahead_m=80.0))
    far = behaviour_feasibility(s, 1, index, CounterfactualConfig(lookahead_m=40.0))
    assert near[Behaviour.TURN_LEFT].status == "feasible"
    assert (
        far[Behaviour.TURN_LEFT].status == "infeasible" and "no junction within 40 m" in far[Behaviour.TURN_LEFT].reason
    )
    assert far[Behaviour.GO_STRAIGHT].status == "undecided"
    assert near[Behaviour.SLOW_DOWN].status == "infeasible"  # it stands: there is no speed to lose


@pytest.mark.parametrize(
    ("station", "open_turns"),
    [
        (72.0, {Behaviour.TURN_LEFT, Behaviour.GO_STRAIGHT}),  # 2 m into the junction: its lane's branches overlap
        (76.0, {Behaviour.TURN_LEFT}),  # 6 m into the left turn: that branch is taken
        (86.0, set()),  # the turn is nearly done: the next junction is beyond it (none within 60 m)
    ],
)
def test_inside_a_junction_the_branch_taken_decides_until_its_turn_is_done(station, open_turns):
    s = scene(four_way(), drive(LEFT_LANE_LEFT, speed=0.0, start=station))  # standing on the left-turn lane
    verdicts = behaviour_feasibility(s, 1, MapIndex.build(s.road_map))
    assert {b for b in TURNS if verdicts[b].status == "feasible"} == open_turns
    if not open_turns:
        assert "no junction within 60 m" in verdicts[Behaviour.TURN_LEFT].reason


def test_without_lane_connectivity_turns_are_undecided_but_the_logged_one_is_kept():
    s = scene(four_way(connectivity=False), drive(LEFT_LANE_STRAIGHT))
    linked = behaviour_feasibility(s, 1, MapIndex.build(s.road_map))  # the lanes meet end to start: linked
    assert linked[Behaviour.TURN_LEFT].status == "feasible"
    index = MapIndex.build(s.road_map, infer_links=False)
    verdicts = behaviour_feasibility(s, 1, index)
    assert {verdicts[b].status for b in TURNS} == {"undecided"}
    assert "lane connectivity" in verdicts[Behaviour.TURN_LEFT].reason
    turns = {a.behaviour: a.logged for a in feasible_alternatives(s, 1, index) if a.behaviour in TURNS}
    assert turns == {Behaviour.GO_STRAIGHT: True}  # what the log shows needs no map to be feasible


def test_without_neighbour_lists_lane_changes_are_undecided():
    s = scene(two_lane_road(neighbours=False), lane_change(0.0))
    verdicts = behaviour_feasibility(s, 1, MapIndex.build(s.road_map))
    assert verdicts[Behaviour.LANE_CHANGE_LEFT].status == "undecided"
    assert "neighbour" in verdicts[Behaviour.LANE_CHANGE_LEFT].reason


def test_on_a_two_lane_road_a_car_can_change_lanes_only_toward_the_other_lane():
    s = scene(two_lane_road(), lane_change(3.5), lane_change(3.5, from_y=3.5))
    index = MapIndex.build(s.road_map)
    right = behaviour_feasibility(s, 1, index)
    assert right[Behaviour.LANE_CHANGE_LEFT].status == "feasible"
    assert right[Behaviour.LANE_CHANGE_RIGHT].status == "infeasible"
    assert right[Behaviour.TURN_LEFT].status == "undecided"  # a road without exit lanes: connectivity unknown
    left = behaviour_feasibility(s, 2, index)
    assert left[Behaviour.LANE_CHANGE_RIGHT].status == "feasible" and left[Behaviour.LANE_CHANGE_LEFT].status == (
        "infeasible"
    )
    alternatives = {a.behaviour: a.logged for a in feasible_alternatives(s, 1, index)}
    assert alternatives[Behaviour.LANE_CHANGE_LEFT] is True  # car 1 moves into the left lane in the log
    assert Behaviour.LANE_CHANGE_RIGHT not in alternatives


def test_pedestrians_get_no_vehicle_behaviours():
    walker = (AgentType.PEDESTRIAN, np.stack([1.2 * TIME, np.full(len(TIME), -3.0)], 1), np.zeros(len(TIME)))
    s = scene(two_lane_road(), walker)
    verdicts = behaviour_feasibility(s, 1, MapIndex.build(s.road_map))
    assert verdicts[Behaviour.STOP].status == "feasible"
    assert verdicts[Behaviour.TURN_LEFT].status == verdicts[Behaviour.SPEED_UP].status == "undecided"


def test_an_interaction_pair_offers_both_going_first_and_yielding():
    s = x_junction_yield()
    index = MapIndex.build(s.road_map)
    logged = logged_facts(s, index)
    assert ("interaction", 1, 2, "yielding/intersection") in logged
    waiter = {(a.behaviour, a.other_id, a.logged): a.facts for a in feasible_alternatives(s, 1, index, logged=logged)}
    assert waiter[(Behaviour.YIELD, 2, True)] == {("interaction", 1, 2, "yielding/intersection")}
    assert waiter[(Behaviour.GO_FIRST, 2, False)] == {("interaction", 1, 2, "passing/intersection_with_yielding")}
    crosser = {(a.behaviour, a.other_id, a.logged) for a in feasible_alternatives(s, 2, index, logged=logged)}
    assert {(Behaviour.GO_FIRST, 1, True), (Behaviour.YIELD, 1, False)} <= crosser
    yield_prompt = next(a for a in feasible_alternatives(s, 2, index, logged=logged) if a.behaviour is Behaviour.YIELD)
    assert yield_prompt.prompt.text == "@2 yields to @1" and yield_prompt.prompt.subtype == "yielding/intersection"


# ---------------------------------------------------------------------------------------------- warnings


def test_an_infeasible_turn_says_which_agent_cannot_do_what_and_what_the_lane_allows():
    s = scene(four_way(right_lane_exits=(14,)), drive(LEFT_LANE_STRAIGHT), drive(RIGHT_LANE_RIGHT))
    index = MapIndex.build(s.road_map)
    right_lane = behaviour_feasibility(s, 2, index)
    left = right_lane[Behaviour.TURN_LEFT]
    assert left.status == "infeasible" and left.target is None
    assert left.message.startswith("@2 cannot turn left: no left turn from its lane at the next junction")
    assert "right turn" in left.message and "straight" not in left.message.split("allows:")[1]
    assert right_lane[Behaviour.GO_STRAIGHT].status == "infeasible"
    assert right_lane[Behaviour.TURN_RIGHT].status == "feasible" and right_lane[Behaviour.TURN_RIGHT].message == ""
    assert behaviour_feasibility(s, 1, index)[Behaviour.TURN_LEFT].status == "feasible"  # the left lane allows it


def test_an_infeasible_lane_change_names_the_side_without_a_lane():
    s = scene(two_lane_road(), lane_change(0.0), lane_change(3.5, from_y=3.5))
    verdicts = behaviour_feasibility(s, 1, MapIndex.build(s.road_map))
    assert verdicts[Behaviour.LANE_CHANGE_RIGHT].message == (
        "@1 cannot change lanes to the right: no lane on its right along its road (within 80 m)"
    )
    assert verdicts[Behaviour.LANE_CHANGE_LEFT].status == "feasible"


# ---------------------------------------------------------------------------------------------- free text


def test_fifty_free_text_prompts_parse_name_known_kinds_and_render_to_valid_prompts():
    prompts = load_free_text_prompts(FREE_TEXT)
    assert len(prompts) == 50 and len({p.text for p in prompts}) == 50
    # The file predates the pull-over, follow and safety-critical kinds;
    # tests/data/prompt_paraphrases.yaml covers the others.
    later = {
        Behaviour.PULL_OVER, Behaviour.FOLLOW, Behaviour.CUT_IN, Behaviour.OVERTAKE_CUT_IN, Behaviour.BRAKE_HARD,
        Behaviour.TAILGATE, Behaviour.RUN_RED_LIGHT, Behaviour.PULL_OUT,
    }  # fmt: skip
    assert {p.behaviour for p in prompts} == set(Behaviour) - later
    for prompt in prompts:
        other = 9 if BEHAVIOURS[prompt.behaviour].is_pair else None
        text = prompt.render(5, other)
        parsed = parse_user_prompt(text, [5, 9])
        assert parsed.mentions[0] == 5 and parsed.mentions == ((5,) if other is None else (5, 9))
        entry, facts = prompt.entry(5, other)
        assert facts == behaviour_facts(prompt.behaviour, 5, other) and entry.roles[5].count("the target agent") == 1
        # phrased outside the template grammar: no phrase of the phrase tables is found in it
        read = recognize_prompt(Prompt(text, parsed.mentions, source="user"))
        assert read.subtype_id is None and read.label_keys == (), text
        reading = read_prompt(text)  # the prompt reader reads it
        assert reading.behaviour is prompt.behaviour and reading.agent == 5, text


@pytest.mark.parametrize(
    ("body", "message"),
    [
        ("prompts: [{text: '{agent} flies', behaviour: fly}]", "unknown behaviour 'fly'"),
        ("prompts: [{text: 'someone stops', behaviour: stop}]", "names no {agent}"),
        ("prompts: [{text: '{agent} waits', behaviour: yield}]", "needs {other}"),
        ("prompts: [{text: '{agent} stops for {other}', behaviour: stop}]", "takes no {other}"),
        ("prompts: 3", "expected a list"),
    ],
)
def test_bad_free_text_files_are_refused_naming_the_entry(tmp_path, body, message):
    path = tmp_path / "bad.yaml"
    path.write_text(body)
    with pytest.raises(InputError, match=message.replace("{", r"\{").replace("}", r"\}")):
        load_free_text_prompts(path)
