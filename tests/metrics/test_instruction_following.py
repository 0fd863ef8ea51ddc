"""Instruction following in closed loop: rollouts judged by the labelers against counterfactual and ground-truth
prompts on constructed scenes, and the IFR aggregation worked by hand."""

from __future__ import annotations

import json

import numpy as np
import pytest
from interdrive.test_counterfactual import (
    LEFT_LANE_LEFT,
    LEFT_LANE_STRAIGHT,
    drive,
    four_way,
    lane_change,
    two_lane_road,
    x_junction_yield,
)
from interdrive.test_ground_truth import straight
from interdrive.test_heuristics import scene

from langtraj.errors import InputError
from langtraj.interdrive.adherence import AdherenceChecker
from langtraj.interdrive.counterfactual import Behaviour, feasible_alternatives, make_alternative
from langtraj.metrics.instruction_following import (
    Judgement,
    instruction_following,
    judge_rollouts,
    rollout_scenario,
)
from langtraj.roads import MapIndex
from langtraj.rollouts.container import Rollouts
from langtraj.scenario import FUTURE_STEPS
from langtraj.scenario.types import StateField


def rollouts_of(*tracks: np.ndarray, ids=None) -> Rollouts:
    """One rollout per entry: each a tuple of per-agent [T, 3] (x, y, heading) over the whole window, of which
    the 80 steps after the current one (10) are kept."""
    ids = np.arange(1, len(tracks[0]) + 1) if ids is None else np.asarray(ids)
    poses = np.stack([np.stack(rollout) for rollout in tracks])[:, :, 11 : 11 + FUTURE_STEPS]  # [R, A, 80, 3]
    return Rollouts(ids, poses[..., 0], poses[..., 1], np.zeros(poses.shape[:3]), poses[..., 2])


def pose(track) -> np.ndarray:
    """[T, 3] x, y, heading of a (type, xy, heading) track."""
    _, xy, heading = track
    return np.concatenate([xy, heading[:, None]], axis=1)


def test_a_rollout_scenario_holds_the_rollout_as_its_future():
    logged = scene(four_way(), drive(LEFT_LANE_STRAIGHT), drive(LEFT_LANE_STRAIGHT, start=0.0))
    turned = rollouts_of((pose(drive(LEFT_LANE_LEFT)),), ids=[1])
    played = rollout_scenario(logged, turned, 0)
    xy = played.agents.states[0, 11:, : StateField.Y + 1]
    assert np.allclose(xy, pose(drive(LEFT_LANE_LEFT))[11:, :2], atol=1e-4)
    assert np.allclose(played.agents.states[0, :11], logged.agents.states[0, :11])  # the history is the log's
    assert np.allclose(played.agents.speed[0, 12:40], 8.0, atol=0.05)  # speed from the rollout's positions
    assert played.agents.valid[1, :11].all() and not played.agents.valid[1, 11:].any()  # not in the rollouts
    with pytest.raises(InputError, match="rollout 1 of 1"):
        rollout_scenario(logged, turned, 1)


def test_a_rollout_that_turns_left_follows_turn_left_and_not_turn_right_nor_straight():
    logged = scene(four_way(), drive(LEFT_LANE_STRAIGHT))
    index = MapIndex.build(logged.road_map)
    checker = AdherenceChecker.build(logged, map_index=index)
    alternatives = feasible_alternatives(logged, 1, index, logged=checker.logged)
    wanted = {a.behaviour: a for a in alternatives}
    right = make_alternative(Behaviour.TURN_RIGHT, 1, checker.logged)  # infeasible here, judged all the same
    prompts = [wanted[Behaviour.TURN_LEFT], wanted[Behaviour.GO_STRAIGHT], right]
    turning = rollouts_of((pose(drive(LEFT_LANE_LEFT)),), (pose(drive(LEFT_LANE_STRAIGHT)),))
    judged = {(j.behaviour, j.rollout): j for j in judge_rollouts(logged, turning, prompts, checker=checker)}
    assert judged[(Behaviour.TURN_LEFT, 0)].followed and not judged[(Behaviour.TURN_LEFT, 1)].followed
    assert not judged[(Behaviour.TURN_RIGHT, 0)].followed and not judged[(Behaviour.TURN_RIGHT, 1)].followed
    assert not judged[(Behaviour.GO_STRAIGHT, 0)].followed and judged[(Behaviour.GO_STRAIGHT, 1)].followed
    assert judged[(Behaviour.TURN_RIGHT, 0)].missing == {("label", 1, "turning_right")}
    assert judged[(Behaviour.GO_STRAIGHT, 0)].ground_truth and not judged[(Behaviour.TURN_LEFT, 0)].ground_truth
    report = instruction_following(judged.values())
    assert report.counterfactual.rate(Behaviour.TURN_LEFT).ifr == 0.5
    assert report.counterfactual.rate(Behaviour.TURN_RIGHT).ifr == 0.0
    assert report.ground_truth.rate(Behaviour.GO_STRAIGHT).ifr == 0.5 and report.ground_truth.macro == 0.5


def test_a_rollout_that_changes_lanes_is_judged_by_the_side_it_moves_to():
    logged = scene(two_lane_road(), lane_change(0.0))  # the log keeps its lane
    index = MapIndex.build(logged.road_map)
    checker = AdherenceChecker.build(logged, map_index=index)
    left = make_alternative(Behaviour.LANE_CHANGE_LEFT, 1, checker.logged)
    right = make_alternative(Behaviour.LANE_CHANGE_RIGHT, 1, checker.logged)
    rollouts = rollouts_of((pose(lane_change(3.5)),), (pose(lane_change(0.0)),))
    judged = {(j.behaviour, j.rollout): j.followed for j in judge_rollouts(logged, rollouts, [left, right])}
    assert judged == {
        (Behaviour.LANE_CHANGE_LEFT, 0): True,
        (Behaviour.LANE_CHANGE_RIGHT, 0): False,
        (Behaviour.LANE_CHANGE_LEFT, 1): False,
        (Behaviour.LANE_CHANGE_RIGHT, 1): False,
    }


def test_going_first_instead_of_yielding_is_judged_on_the_pair():
    logged = x_junction_yield()
    index = MapIndex.build(logged.road_map)
    checker = AdherenceChecker.build(logged, map_index=index)
    prompts = [a for a in feasible_alternatives(logged, 1, index, logged=checker.logged) if a.other_id == 2]
    assert {(a.behaviour, a.logged) for a in prompts} == {(Behaviour.GO_FIRST, False), (Behaviour.YIELD, True)}
    as_logged = np.stack([logged.agents.states[a][:, [0, 1, 3]] for a in range(2)])
    step = np.arange(len(logged.timestamps))
    creep = np.where(step < 10, 0.0, 2.0)  # car 1 sets off at the current step and reaches the centre at step 50
    brake = np.interp(step, [20, 40, 65, 66], [10.0, 0.0, 0.0, 10.0])  # car 2 stops 10 m short until step 65
    first = (straight(-8, 0, 0, creep)[:, :3], straight(0, -40, np.pi / 2, brake)[:, :3])
    rollouts = rollouts_of(first, tuple(as_logged))
    judged = {(j.behaviour, j.rollout): j.followed for j in judge_rollouts(logged, rollouts, prompts, checker=checker)}
    assert judged == {
        (Behaviour.GO_FIRST, 0): True,
        (Behaviour.YIELD, 0): False,
        (Behaviour.GO_FIRST, 1): False,
        (Behaviour.YIELD, 1): True,
    }


def test_a_prompt_about_an_agent_outside_the_rollouts_is_refused():
    logged = x_junction_yield()
    checker = AdherenceChecker.build(logged)
    prompt = make_alternative(Behaviour.YIELD, 1, checker.logged, 2)
    only_one = rollouts_of((straight(-8, 0, 0, 0.0)[:, :3],), ids=[1])
    with pytest.raises(InputError, match="no track @2"):
        judge_rollouts(logged, only_one, [prompt], checker=checker)
    assert judge_rollouts(logged, only_one, []) == ()


def _judgement(track, behaviour, followed, rollout, ground_truth=False, scenario="s"):
    facts = frozenset({("label", track, behaviour.value)})
    return Judgement(scenario, track, behaviour, ground_truth, facts, rollout, followed)


def test_ifr_averages_rollouts_per_prompt_then_prompts_per_kind_then_kinds():
    judgements = [
        # counterfactual turn_left: prompt A follows in 1 of 2 rollouts, prompt B in 2 of 2 -> (0.5 + 1) / 2
        _judgement(1, Behaviour.TURN_LEFT, True, 0),
        _judgement(1, Behaviour.TURN_LEFT, False, 1),
        _judgement(2, Behaviour.TURN_LEFT, True, 0),
        _judgement(2, Behaviour.TURN_LEFT, True, 1),
        # counterfactual stop: one prompt, 1 of 4 rollouts; the same track in another scene is another prompt
        *[_judgement(1, Behaviour.STOP, r == 0, r) for r in range(4)],
        _judgement(1, Behaviour.STOP, True, 0, scenario="t"),
        # ground truth: speed_up followed in 3 of 3
        *[_judgement(3, Behaviour.SPEED_UP, True, r, ground_truth=True) for r in range(3)],
    ]
    report = instruction_following(judgements)
    cf, gt = report.counterfactual, report.ground_truth
    assert cf.rate(Behaviour.TURN_LEFT).ifr == pytest.approx(0.75) and cf.rate(Behaviour.TURN_LEFT).prompts == 2
    assert cf.rate(Behaviour.STOP).ifr == pytest.approx((0.25 + 1.0) / 2) and cf.rate(Behaviour.STOP).judgements == 5
    assert cf.macro == pytest.approx((0.75 + 0.625) / 2) and cf.prompts == 4 and cf.judgements == 9
    assert [r.behaviour for r in cf.per_kind] == [Behaviour.TURN_LEFT, Behaviour.STOP]  # behaviour-kind order
    assert gt.macro == 1.0 and gt.prompts == 1 and gt.judgements == 3 and gt.rate(Behaviour.TURN_LEFT) is None
    as_json = json.loads(json.dumps(report.to_json()))
    assert as_json["f_ifr"]["per_kind"]["stop"] == {"ifr": 0.625, "prompts": 2, "judgements": 5}
    assert as_json["gt_ifr"]["macro"] == 1.0
    empty = instruction_following([])
    assert empty.ground_truth.macro is None and empty.counterfactual.per_kind == ()
    assert json.dumps([j.to_json() for j in judgements])  # every judgement is JSON-able
