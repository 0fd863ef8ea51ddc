"""What a typed prompt steers (`sim.prompts.prompt_steering`, from its one reading `read_prompts`): the behaviour
read, its target as guidance, the candidate judge's ask, and one line per prompt saying so; each lever can be switched
off."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from interdrive.test_counterfactual import (
    HALF,
    LEFT_LANE_LEFT,
    LEFT_LANE_STRAIGHT,
    RIGHT_LANE_STRAIGHT,
    drive,
    four_way,
    two_lane_road,
)
from interdrive.test_heuristics import TIME, along, scene
from roads.test_index import line

from langtraj.errors import InputError
from langtraj.guidance import RouteCost
from langtraj.interdrive.behaviour import Behaviour
from langtraj.interdrive.dataset import PromptEntry
from langtraj.interdrive.prompts import parse_user_prompt
from langtraj.interdrive.targets import BehaviourTarget
from langtraj.model.checkpoint import load_model
from langtraj.scenario import AgentType
from langtraj.sim import prompts
from langtraj.sim.checkpoints import shipped_checkpoint
from langtraj.sim.config import ALL_LEVERS, PromptLevers, SimRequest
from langtraj.sim.policies import GUIDANCE_ONLY, GuidanceBaselinePolicy
from langtraj.sim.prompts import conditioning_sentence, prompt_steering, read_prompts
from langtraj.sim.world import SimWorld

ORIGIN = (0.0, 0.0, 0.0)


def _crossing_scene():
    xy, heading = along(line(-80, -HALF, -10, -HALF), 40.0 + 8.0 * TIME)  # eastbound on lane 41
    return scene(four_way(), drive(LEFT_LANE_STRAIGHT), drive(RIGHT_LANE_STRAIGHT), (AgentType.VEHICLE, xy, heading))


def test_a_read_prompt_steers_by_its_target_and_is_judged_by_selection():
    s = _crossing_scene()
    rows = np.arange(3)
    steering = prompt_steering(s, read_prompts(["@2, take the next right"]), rows, ORIGIN, ALL_LEVERS)
    (reading,) = steering.readings
    assert reading.behaviour is Behaviour.TURN_RIGHT and reading.agent == 2
    (steer,) = steering.steerings
    assert steer.slot == 1 and any(isinstance(t.cost, RouteCost) for t in steer.terms(0, 80))
    (ask,) = steering.asks
    assert (ask.track_id, ask.slot, ask.behaviour) == (2, 1, Behaviour.TURN_RIGHT)
    (note,) = steering.notes
    assert note.startswith('read as: @2 turn_right ("take the next right")') and "adherence-first selection" in note
    assert steering.to_json()["targets"][0]["behaviour"] == "turn_right"


def test_a_yield_also_steers_the_other_agent_through_first():
    s = _crossing_scene()
    steering = prompt_steering(s, read_prompts(["@1 yields to @3"]), np.arange(3), ORIGIN, ALL_LEVERS)
    assert [x.target.behaviour for x in steering.steerings] == [Behaviour.YIELD, Behaviour.GO_FIRST]
    assert [x.slot for x in steering.steerings] == [0, 2]
    assert "@3 toward it passes the conflict point" in steering.notes[0]
    undriven = prompt_steering(s, read_prompts(["@1 yields to @3"]), np.arange(2), ORIGIN, ALL_LEVERS)  # @3: undriven
    assert [x.slot for x in undriven.steerings] == [0]
    assert "@3 unsteered (the model does not drive it)" in undriven.notes[0]


def test_unread_prompts_and_missing_targets_say_what_steers_them():
    s = _crossing_scene()
    unread = prompt_steering(s, read_prompts(["@1 does a little dance"]), np.arange(3), ORIGIN, ALL_LEVERS)
    assert not unread.steerings and not unread.asks
    assert unread.notes[0].startswith("not read:") and "it steers by its text alone" in unread.notes[0]
    assert "the prompt steers by text alone" not in unread.notes[0]  # said once
    left = read_prompts(["@2 turns left at the next intersection"])
    no_target = prompt_steering(s, left, np.arange(3), ORIGIN, ALL_LEVERS)
    assert not no_target.steerings and len(no_target.asks) == 1  # the judge still asks; the map gives no target
    assert any("no target: @2 cannot turn left" in n for n in no_target.notes)


@pytest.mark.parametrize(
    ("levers", "guided", "judged"),
    [(PromptLevers(guidance=False), 0, 1), (PromptLevers(selection=False), 1, 0), (PromptLevers(text=False), 1, 1)],
)
def test_each_lever_can_be_switched_off(levers, guided, judged):
    steering = prompt_steering(_crossing_scene(), read_prompts(["@2 stops"]), np.arange(3), ORIGIN, levers)
    assert (len(steering.steerings), len(steering.asks)) == (guided, judged)
    assert ("text" in steering.notes[0]) is levers.text


def test_a_prompt_about_an_agent_the_model_does_not_drive_is_refused():
    with pytest.raises(InputError, match="@3 is not among the agents the model drives"):
        prompt_steering(_crossing_scene(), read_prompts(["@3 stops"]), np.arange(2), ORIGIN, ALL_LEVERS)


def test_the_warnings_come_from_the_same_reading():
    no_target = prompt_steering(_crossing_scene(), read_prompts(["@2 turns left"]), np.arange(3), ORIGIN, ALL_LEVERS)
    assert [w.split(":")[0] for w in no_target.warnings] == ["@2 cannot turn left"]
    assert not prompt_steering(_crossing_scene(), read_prompts(["@2 stops"]), np.arange(3), ORIGIN, ALL_LEVERS).warnings


def test_a_condition_on_the_agents_that_holds_at_the_start_already_is_warned_about_and_starts_at_once():
    # @1 12 m (bumpers) ahead of @2 in one lane of a straight road at 10 m/s
    def east(x: float):
        return AgentType.VEHICLE, np.stack([x + 10.0 * TIME, np.zeros_like(TIME)], axis=1), np.zeros_like(TIME)

    lead = scene(two_lane_road(), east(16.5), east(0.0))
    near = "When @2 is within 20 m of @1, @1 brakes hard in front of @2"
    (warning,) = prompt_steering(lead, read_prompts([near]), np.arange(2), ORIGIN, ALL_LEVERS).warnings
    assert warning == (
        "the start of @1's brake_hard (when @2 is within 20 m of @1) holds already at the start (@2 12 m from @1): it "
        "starts at once, not when that comes about"
    )
    far = near.replace("20 m", "10 m")
    assert not prompt_steering(lead, read_prompts([far]), np.arange(2), ORIGIN, ALL_LEVERS).warnings


def test_a_prompt_of_two_clauses_steers_both_agents():
    s = _crossing_scene()
    readings = read_prompts(["@2 stops, and @3 speeds up"])
    assert [(r.agent, r.behaviour) for r in readings] == [(2, Behaviour.STOP), (3, Behaviour.SPEED_UP)]
    steering = prompt_steering(s, readings, np.arange(3), ORIGIN, ALL_LEVERS)
    assert [(x.slot, x.target.behaviour) for x in steering.steerings] == [(1, Behaviour.STOP), (2, Behaviour.SPEED_UP)]
    assert [a.track_id for a in steering.asks] == [2, 3] and len(steering.notes) == 2
    together = read_prompts(["@1 and @2 stop"])  # a coordinated subject: each agent its own stop
    assert [(r.agent, r.behaviour, r.clause) for r in together] == [
        (1, Behaviour.STOP, "@1 stop"), (2, Behaviour.STOP, "@2 stop")
    ]  # fmt: skip


def test_a_yield_leaves_the_other_agent_to_its_own_clause():
    s = _crossing_scene()
    steering = prompt_steering(s, read_prompts(["@1 yields to @3; @3 stops"]), np.arange(3), ORIGIN, ALL_LEVERS)
    assert [(x.slot, x.target.behaviour) for x in steering.steerings] == [(0, Behaviour.YIELD), (2, Behaviour.STOP)]


@pytest.mark.parametrize(
    ("text", "error"),
    [
        ("@1 stops and @2 does a little dance", r"clause '@2 does a little dance' of .* cannot be read"),
        ("@1 stops. @1 turns left", r"@1 is asked twice \('@1 stops' and '@1 turns left'\)"),
    ],
)
def test_a_clause_that_cannot_be_read_or_asks_an_agent_again_is_one_line_error(text, error):
    with pytest.raises(InputError, match=error):
        read_prompts([text])
    assert len(read_prompts([text], strict=False)) == 2  # a dataset prompt's sentence is never refused
    alone = read_prompts(["@1 does a little dance"])  # one clause not read: it steers by its text alone
    assert len(alone) == 1 and not alone[0].read


def test_a_stop_asked_with_a_pull_over_the_map_refuses_is_kept_on_its_own():
    s = _crossing_scene()  # @1 drives the left lane: a lane lies on its right, so it cannot pull over
    (reading,) = read_prompts(["@1 pulls over and comes to a stop"])
    assert reading.behaviour is Behaviour.PULL_OVER and reading.also == (Behaviour.STOP,)
    steering = prompt_steering(s, (reading,), np.arange(3), ORIGIN, ALL_LEVERS)
    ((steer,), (ask,)) = steering.steerings, steering.asks
    assert steer.target.behaviour is Behaviour.STOP and ask.behaviour is Behaviour.STOP
    (warning,) = steering.warnings
    assert warning.startswith("@1 cannot pull over: a lane lies on its right") and warning.endswith(
        "its stop is kept on its own"
    )
    assert "so its stop alone" in steering.notes[0]
    plain = prompt_steering(s, read_prompts(["@1 pulls over"]), np.arange(3), ORIGIN, ALL_LEVERS)
    assert not plain.steerings and not plain.warnings[0].endswith("kept on its own")  # nothing else was asked


@pytest.fixture(scope="module")
def loaded():
    return load_model(shipped_checkpoint())


def _typed(text: str) -> PromptEntry:
    return PromptEntry.of(parse_user_prompt(text, [1, 2, 3]))


def _baseline_state(policy, s):
    world = SimWorld(s, policy.drives(s, np.arange(3)), 1)
    return policy.reset(world, 0)


def test_the_guidance_baseline_reads_a_typed_prompt_once_and_takes_no_other_levers(loaded, monkeypatch):
    model, data = loaded
    typed = _typed("@2 stops")
    for levers in (PromptLevers(selection=False), PromptLevers(guidance=False)):
        with pytest.raises(InputError, match=r"levers.*takes no other levers"):
            GuidanceBaselinePolicy(model, data, SimRequest(levers=levers), prompt=typed)
    assert (
        GuidanceBaselinePolicy(model, data, SimRequest(levers=ALL_LEVERS), prompt=typed).request.levers == GUIDANCE_ONLY
    )
    read = prompts.read_clauses
    texts: list[str] = []
    monkeypatch.setattr(prompts, "read_clauses", lambda text: texts.append(text) or read(text))
    policy = GuidanceBaselinePolicy(model, data, SimRequest(levers=GUIDANCE_ONLY), prompt=typed)
    state = _baseline_state(policy, _crossing_scene())
    assert texts == ["@2 stops"]  # read once: the refusal check, the steering and the warnings take that reading
    assert [s.slot for s in state.prompt.steering.steerings] == [1]
    assert policy.describe()["prompt_read_as"] == {"behaviour": "stop", "subtype": None, "labels": ["static"]}


def test_the_guidance_baseline_falls_back_to_the_label_library_for_a_labelled_prompt_only(loaded):
    model, data = loaded
    unread = _typed("@2 does a little dance")
    with pytest.raises(InputError, match="needs a prompt whose behaviour it can read"):
        GuidanceBaselinePolicy(model, data, prompt=unread)
    labelled = GuidanceBaselinePolicy(model, data, prompt=replace(unread, labels=("slowing_down",)))
    realism = labelled.realism_terms(3)
    state = _baseline_state(labelled, _crossing_scene())
    assert not state.prompt.steering.steerings and len(state.terms) > len(realism)  # the library's terms steer
    no_target = GuidanceBaselinePolicy(model, data, prompt=_typed("@2 turns left"))
    state = _baseline_state(no_target, _crossing_scene())
    assert not state.prompt.steering.steerings and len(state.terms) == len(realism)  # typed: its reading alone


def test_kinds_the_model_never_saw_are_conditioned_on_the_sentence_of_what_their_target_does():
    path = np.zeros((2, 2))
    cut_in = BehaviourTarget(12, Behaviour.CUT_IN, path, "", other_id=7, side="right")
    brake = BehaviourTarget(12, Behaviour.BRAKE_HARD, path, "", other_id=7, speed=0.0)
    assert conditioning_sentence(cut_in) == "@12 changes lanes to the right"
    assert conditioning_sentence(brake) == "@12 comes to a stop and stands still"
    overtake = BehaviourTarget(12, Behaviour.OVERTAKE_CUT_IN, path, "", other_id=7, side="left")
    assert conditioning_sentence(overtake) == "@12 changes lanes to the left"
    red = BehaviourTarget(12, Behaviour.RUN_RED_LIGHT, path, "", other_id=7)  # a pair sentence names the other
    assert conditioning_sentence(red) == "@12 takes the right of way over @7"
    pull_out = BehaviourTarget(12, Behaviour.PULL_OUT, path, "", other_id=7)
    assert conditioning_sentence(pull_out) == "@12 takes the right of way over @7"
    assert conditioning_sentence(BehaviourTarget(12, Behaviour.TAILGATE, path, "", other_id=7)) is None  # seen
    assert conditioning_sentence(BehaviourTarget(12, Behaviour.STOP, path, "", speed=0.0)) is None


def test_a_turn_then_a_stop_steers_the_turn_and_a_stop_past_the_junctions_exit():
    near = drive(LEFT_LANE_LEFT, start=52.0)  # 10 m before the junction at 8 m/s, in the lane that turns left
    s = scene(four_way(), near, drive(RIGHT_LANE_STRAIGHT))
    steering = prompt_steering(s, read_prompts(["@1 turns left and then stops"]), np.arange(2), ORIGIN, ALL_LEVERS)
    (reading,) = steering.readings
    assert (reading.behaviour, reading.then) == (Behaviour.TURN_LEFT, Behaviour.STOP)
    (steer,) = steering.steerings
    target = steer.target
    assert target.behaviour is Behaviour.TURN_LEFT and target.stop
    exit_at = 10.0 + 11.75 * np.pi / 2  # the junction's entry 10 m ahead, then the left turn's arc
    assert target.station_of_goal == pytest.approx(exit_at + 7.0, abs=0.6)  # wholly out of the junction
    assert 5.0 < target.settled_s <= 7.0  # driving on, then braking at 2 m/s^2, standing by 7 s
    costs = {type(t.cost).__name__ for t in steer.terms(0, 80)}
    assert {"RouteCost", "StationCost", "TargetSpeedCost"} <= costs
    (ask,) = steering.asks
    assert (ask.behaviour, ask.then) == (Behaviour.TURN_LEFT, Behaviour.STOP)
    assert "its exit 28 m ahead, then a stop 35 m ahead" in steering.notes[0] and not steering.warnings
    far = prompt_steering(
        _crossing_scene(), read_prompts(["@1 turns left and then stops"]), np.arange(3), ORIGIN, ALL_LEVERS
    )  # 32 m before the junction at 8 m/s: no stop past it within the 8 s
    assert not far.steerings
    assert far.warnings == (
        "@1 cannot turn left: then stop: a stop past the junction (57 m ahead) is beyond its reach in 7 s",
    )


def test_a_lane_change_then_a_stop_stops_in_the_new_lane():
    s = _crossing_scene()
    steering = prompt_steering(
        s, read_prompts(["@2 changes to the left lane and stops"]), np.arange(3), ORIGIN, ALL_LEVERS
    )
    (steer,) = steering.steerings
    assert steer.target.behaviour is Behaviour.LANE_CHANGE_LEFT and steer.target.stop
    assert steer.target.joins_m == pytest.approx(10.6, abs=0.1)  # its lead-in meets the left lane 10 m ahead
    assert steer.target.station_of_goal == pytest.approx(4.0 * 8.0 + 2.0, abs=0.01)  # 4 s at 8 m/s, then 2 m
    assert steering.asks[0].then is Behaviour.STOP


def test_a_stop_after_a_manoeuvre_without_its_time_to_stand_is_an_error_not_a_guess():
    near = drive(LEFT_LANE_LEFT, start=52.0)
    s = scene(four_way(), near, drive(RIGHT_LANE_STRAIGHT))
    steering = prompt_steering(s, read_prompts(["@1 turns left and then stops"]), np.arange(2), ORIGIN, ALL_LEVERS)
    (steer,) = steering.steerings
    untimed = replace(steer, target=replace(steer.target, settled_s=None))
    with pytest.raises(ValueError, match="needs its time to stand"):
        untimed.terms(0, 80)
