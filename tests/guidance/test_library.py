"""The fixed CTG++-style library: it covers the taxonomy and builds sensible, working terms."""

from __future__ import annotations

import math

import pytest
import torch

from langtraj.errors import InputError
from langtraj.guidance import (
    INTERACTION_GUIDANCE,
    LABEL_GUIDANCE,
    GoalCost,
    GuidanceTerm,
    NoCollisionCost,
    TargetSpeedCost,
    terms_for,
    terms_for_prompt,
)
from langtraj.interdrive.prompts import Prompt
from langtraj.interdrive.taxonomy import LABELS_BY_KEY, SUBTYPES

from .helpers import make_scene

# Target agent 0 at the origin heading +x at 6 m/s; the other agent 1 ahead at 4 m/s; a bystander.
STATE = torch.tensor([[0.0, 0.0, 0.0, 6.0], [15.0, 0.0, 0.0, 4.0], [0.0, 10.0, 0.0, 0.0]])
ROLES = {"target": 0, "other": 1}
LANES = [[[-50.0, 0.0], [100.0, 0.0]], [[-50.0, 3.5], [100.0, 3.5]]]
ROAD = [[[-50.0, -2.0], [100.0, -2.0]], [[100.0, 6.0], [-50.0, 6.0]]]


def test_every_subtype_and_label_of_the_taxonomy_has_an_entry():
    assert set(INTERACTION_GUIDANCE) == {s.id for s in SUBTYPES}
    assert set(LABEL_GUIDANCE) == set(LABELS_BY_KEY)


@pytest.mark.parametrize("other", [1, None])
def test_every_entry_builds_terms_that_evaluate(other):
    scene = make_scene(3, lanes=LANES, road_edges=ROAD)
    states = torch.randn(2, 3, 80, 4, generator=torch.Generator().manual_seed(0))
    mentions = {0: 0} if other is None else {0: 0, 1: other}
    for subtype in INTERACTION_GUIDANCE:
        for term in terms_for_prompt(mentions, STATE, subtype_id=subtype):
            assert isinstance(term, GuidanceTerm)
            assert torch.isfinite(term.cost(states, scene)).all(), subtype
            if other is None:
                assert not isinstance(term.cost, NoCollisionCost), subtype
    for key in LABEL_GUIDANCE:
        for term in terms_for_prompt(mentions, STATE, label_keys=[key]):
            assert torch.isfinite(term.cost(states, scene)).all(), key


def test_yielding_slows_down_first_and_keeps_clear_of_the_other_agent():
    terms = terms_for_prompt(ROLES, STATE, subtype_id="yielding/intersection")
    speeds = [t.cost for t in terms if isinstance(t.cost, TargetSpeedCost)]
    avoid = [t.cost for t in terms if isinstance(t.cost, NoCollisionCost)]
    assert len(speeds) == 1 and speeds[0].speeds[0] < 6.0 and speeds[0].end == 40
    assert len(avoid) == 1 and avoid[0].slots == (0,) and avoid[0].others == (1,)


def test_speed_labels_set_their_targets_from_the_current_speed():
    def target(key: str) -> float:
        (term,) = terms_for_prompt(ROLES, STATE, label_keys=[key])
        return term.cost.speeds[0]

    assert target("speeding_up") > 6.0 > target("slowing_down")
    assert target("parked") == target("static") == 0.0
    assert target("constant_speed") == pytest.approx(6.0)
    (follow,) = [
        t.cost
        for t in terms_for_prompt(ROLES, STATE, subtype_id="following/with_lead")
        if t.cost.name == "target_speed"
    ]
    assert follow.speeds[0] == pytest.approx(4.0)  # the lead's speed


def test_turns_and_lane_changes_place_goals_to_the_right_side():
    def goal(key: str, params=None) -> tuple[float, float]:
        terms = terms_for_prompt(ROLES, STATE, label_keys=[key], label_params=params)
        (cost,) = [t.cost for t in terms if isinstance(t.cost, GoalCost)]
        return cost.goal

    assert goal("turning_left")[1] > 5.0 and goal("turning_right")[1] < -5.0
    assert goal("changing_lanes", {"changing_lanes": {"from": "middle", "to": "leftmost"}})[1] == pytest.approx(3.5)
    assert goal("changing_lanes", {"changing_lanes": {"from": "leftmost", "to": "rightmost"}})[1] == pytest.approx(-3.5)
    no_direction = terms_for_prompt(ROLES, STATE, label_keys=["changing_lanes"])
    assert not any(isinstance(t.cost, GoalCost) for t in no_direction)
    rotated = STATE.clone()
    rotated[0, 2] = math.pi / 2  # heading north: left is -x
    (turn,) = terms_for_prompt({0: 0}, rotated, label_keys=["turning_left"])
    assert turn.cost.goal[0] < -5.0


def test_pulling_over_stops_at_a_goal_to_the_right_on_the_road():
    terms = terms_for_prompt(ROLES, STATE, label_keys=["pulling_over"])
    (goal,) = [t.cost for t in terms if isinstance(t.cost, GoalCost)]
    (speed,) = [t.cost for t in terms if isinstance(t.cost, TargetSpeedCost)]
    assert goal.goal[0] > 5.0 and goal.goal[1] == pytest.approx(-1.75)
    assert speed.speeds[0] == 0.0 and speed.start == 40
    assert "on_road" in [t.cost.name for t in terms]


def test_roles_may_be_named_and_a_prompt_maps_its_mentions():
    by_index = terms_for_prompt({0: 0, 1: 1}, STATE, subtype_id="following/tailgating", label_keys=["speeding_up"])
    by_name = terms_for_prompt(
        {"the target agent": 0, "other agent1": 1}, STATE, subtype_id="following/tailgating", label_keys=["speeding_up"]
    )
    assert [t.cost.name for t in by_index] == [t.cost.name for t in by_name]
    assert "collision" in [t.cost.name for t in by_index]  # tailgating closes the gap
    prompt = Prompt(
        "@12 yields to @7 at the intersection, then speeds up", (12, 7), "yielding/intersection", ("speeding_up",)
    )
    terms = terms_for(prompt, {12: 2, 7: 0}, STATE)
    assert {t.cost.slots for t in terms} == {(2,)}
    assert [t.cost.others for t in terms if isinstance(t.cost, NoCollisionCost)] == [(0,)]
    alone = terms_for(prompt, {12: 2}, STATE)  # the other agent is not simulated
    assert not any(isinstance(t.cost, NoCollisionCost) for t in alone)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"subtype_id": "yielding/politely"}, "unknown interaction subtype 'yielding/politely'"),
        ({"label_keys": ["dancing"]}, "unknown single-agent label 'dancing'"),
        ({"mentions": {"boss": 0}}, "unknown role 'boss'"),
        ({"mentions": {"other": 1}}, "mentions name no target agent"),
        ({"mentions": {0: 7}}, "target slot 7 is out of range for 3 agents"),
        ({"current_state": torch.zeros(3, 3)}, r"current_state must be \[A, 4\]"),
    ],
)
def test_bad_requests_are_refused(kwargs, message):
    args = {"mentions": ROLES, "current_state": STATE, **kwargs}
    with pytest.raises(InputError, match=message):
        terms_for_prompt(**args)
    prompt = Prompt("@5 speeds up", (5,), None, ("speeding_up",))
    with pytest.raises(InputError, match="target agent of prompt '@5 speeds up' is not among the simulated"):
        terms_for(prompt, {6: 0}, STATE)
