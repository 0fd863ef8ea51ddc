"""What one replan of a prompted simulation leaves the next: the executed plan shifted to the replan and offered
again as a candidate (`PromptReplans.offer_kept_plans`), made into states the way a fresh candidate is."""

from __future__ import annotations

from types import SimpleNamespace

import pytest
import torch

from langtraj.interdrive.behaviour import Behaviour
from langtraj.sim.adherence import Ask
from langtraj.sim.prompt_replan import PromptReplans, shifted_plan

PER_ACTION = 5  # scenario steps per action
N, T = 4, 20  # actions and states of a plan


def test_a_plan_shifts_by_the_actions_executed_and_holds_its_last_speed_and_heading():
    actions = torch.arange(1.0, N * 2 + 1).reshape(N, 2)
    left = shifted_plan(actions, 2 * PER_ACTION, PER_ACTION)
    assert torch.equal(left[:2], actions[2:]) and torch.equal(left[2:], torch.zeros(2, 2))
    assert torch.equal(shifted_plan(actions, 0, PER_ACTION), actions)
    assert shifted_plan(actions, PER_ACTION + 1, PER_ACTION) is None  # between two actions
    assert shifted_plan(actions, N * PER_ACTION, PER_ACTION) is None  # past the plan's end


def _replans(slot: int = 0, other: int | None = None) -> PromptReplans:
    ask = Ask(track_id=1, row=slot, slot=slot, behaviour=Behaviour.STOP, other_slot=other)
    return PromptReplans(judge=SimpleNamespace(asks=[ask]))  # only its asks are read here


def _realise(calls: list):
    """A stand-in for the policy's realiser: records the actions it is given and makes two candidates of them (as
    the policy makes a projected and a raw one), states all 7."""

    def realise(actions: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        calls.append(actions.clone())
        r, a = actions.shape[:2]
        return torch.full((2, r, a, T, 4), 7.0), torch.stack([actions, actions])

    return realise


def test_the_kept_plan_joins_the_candidates_made_as_a_fresh_one():
    replans = _replans()
    executed = torch.randn(1, 2, N, 2)  # [R, A, N, 2]
    replans.keep(10, [0], executed)
    states, actions = torch.zeros(3, 1, 2, T, 4), torch.randn(3, 1, 2, N, 2)
    calls: list = []
    out_states, out_actions = replans.offer_kept_plans(20, [0], states, actions, PER_ACTION, _realise(calls))
    assert out_states.shape[0] == out_actions.shape[0] == 5  # three sampled, two made of the kept plan
    (given,) = calls
    assert torch.equal(given[0, 0], shifted_plan(executed[0, 0], 10, PER_ACTION))  # the prompted agent's own plan
    assert torch.equal(given[0, 1], actions[0, 0, 1])  # the others as in candidate 0
    assert torch.equal(out_states[3:], torch.full((2, 1, 2, T, 4), 7.0)) and torch.equal(out_states[:3], states)


@pytest.mark.parametrize("step", [15 + 2, 10 + N * PER_ACTION])
def test_no_kept_plan_is_offered_between_actions_or_past_its_end(step):
    replans = _replans()
    replans.keep(10, [0], torch.randn(1, 2, N, 2))
    states, actions = torch.zeros(3, 1, 2, T, 4), torch.zeros(3, 1, 2, N, 2)
    calls: list = []
    out, _ = replans.offer_kept_plans(step, [0], states, actions, PER_ACTION, _realise(calls))
    assert out is states and not calls


def test_nothing_is_kept_or_offered_without_a_judge_or_before_a_plan():
    plain = PromptReplans()
    plain.keep(10, [0], torch.randn(1, 2, N, 2))
    assert plain.kept == {}
    states, actions = torch.zeros(3, 2, 2, T, 4), torch.zeros(3, 2, 2, N, 2)
    judged = _replans()
    judged.keep(10, [0], torch.randn(1, 2, N, 2))  # rollout 1 has no plan yet
    for replans in (plain, judged):
        out, _ = replans.offer_kept_plans(20, [0, 1], states, actions, PER_ACTION, _realise([]))
        assert out is states


def test_a_pair_behaviour_keeps_both_agents_plans():
    replans = _replans(slot=0, other=2)
    executed = torch.randn(1, 3, N, 2)
    replans.keep(10, [0], executed)
    calls: list = []
    actions = torch.randn(3, 1, 3, N, 2)
    replans.offer_kept_plans(20, [0], torch.zeros(3, 1, 3, T, 4), actions, PER_ACTION, _realise(calls))
    (given,) = calls
    for slot in (0, 2):
        assert torch.equal(given[0, slot], shifted_plan(executed[0, slot], 10, PER_ACTION))
    assert torch.equal(given[0, 1], actions[0, 0, 1])
