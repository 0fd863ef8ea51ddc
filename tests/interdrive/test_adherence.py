"""Prompt adherence: a prompt's facts, and whether a replaced future still shows them."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from roads.test_index import three_lane_road

from langtraj.interdrive.adherence import AdherenceChecker, prompt_facts, prompt_for_sentence
from langtraj.interdrive.dataset import PromptEntry, WindowRecord
from langtraj.interdrive.labels import WindowLabels

from .test_heuristics import TIME, car_on_lane, scene


def _prompt(mentions, labels=(), subtype=None) -> PromptEntry:
    roles = {m: f"sentence of {m} in {'/'.join(labels) or subtype}" for m in mentions}
    return PromptEntry("@" + " @".join(map(str, mentions)), tuple(mentions), roles, subtype, tuple(labels), "heuristic")


def _speeding_up_scene():
    return scene(three_lane_road(), car_on_lane(0.0, np.clip(4.0 + 1.5 * (TIME - 1.0), 4.0, None)))


def test_a_prompt_states_its_targets_labels_and_its_interaction():
    assert prompt_facts(_prompt((5,), ("speeding_up", "going_straight"))) == {
        ("label", 5, "speeding_up"),
        ("label", 5, "going_straight"),
    }
    facts = prompt_facts(_prompt((5, 9), ("slowing_down",), "yield/yield_to"))
    assert facts == {("label", 5, "slowing_down"), ("interaction", 5, 9, "yield/yield_to")}
    assert prompt_facts(_prompt((), ())) == frozenset()


def test_the_logged_future_follows_its_own_labels_and_a_braking_sample_does_not():
    logged = _speeding_up_scene()
    checker = AdherenceChecker.build(logged)
    prompt = _prompt((1,), ("speeding_up",))
    wanted = checker.checkable(prompt)
    assert wanted == {("label", 1, "speeding_up")}
    assert checker.follows(wanted, checker.facts(logged))

    braking = car_on_lane(0.0, np.clip(15.0 - 1.5 * TIME, 0.0, None))
    states = logged.agents.states.copy()
    future = slice(logged.current_index + 1, None)
    states[0, future, :2] = braking[1][future]
    sample = replace(logged, agents=replace(logged.agents, states=states))
    assert not checker.follows(wanted, checker.facts(sample))


def test_facts_the_labelers_cannot_reproduce_on_the_log_are_not_checked():
    checker = AdherenceChecker.build(_speeding_up_scene())
    assert checker.checkable(_prompt((1,), ("slowing_down",))) == frozenset()
    assert checker.checkable(_prompt((1, 2), ("speeding_up",), "yield/yield_to")) == {("label", 1, "speeding_up")}


def test_a_sentence_is_traced_back_to_its_prompt():
    first, second = _prompt((1,), ("speeding_up",)), _prompt((1, 2), (), "yield/yield_to")
    record = WindowRecord("s", "src", 0, 0, 10, 91, (1, 2), WindowLabels("s"), (first, second))
    assert prompt_for_sentence(record, 2, second.roles[2]) is second
    assert prompt_for_sentence(record, 1, first.roles[1]) is first
    assert prompt_for_sentence(record, 1, "no such sentence") is None
