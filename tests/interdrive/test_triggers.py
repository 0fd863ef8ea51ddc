"""Timing words read as triggers (`interdrive.reader.when`) and checked on a scene as it is now
(`interdrive.triggers`): a time, a distance or headway, a stop, a pass, a sequence; words that say none are refused
with the reason."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from interdrive.test_counterfactual import two_lane_road
from interdrive.test_heuristics import scene
from langtraj.interdrive.reader.when import trigger_of
from langtraj.interdrive.triggers import AfterDone, AtTime, Now, Passed, Stopped, Within
from langtraj.scenario.types import AgentType


@pytest.mark.parametrize(
    ("words", "expected"),
    [
        ("after 3 s", AtTime(3.0)),
        ("in three seconds", AtTime(3.0)),
        ("at t = 4", AtTime(4.0)),
        ("2.5 seconds from now", AtTime(2.5)),
        ("when @1 is within 20 m of @7", Within(1, 7, metres=20.0)),
        ("When @1 is within 20 m", Within(1, 7, metres=20.0)),  # of the agent asked
        ("once @1 is 2 s behind @7", Within(1, 7, seconds=2.0)),
        ("as soon as @1 gets within two seconds of @7", Within(1, 7, seconds=2.0)),
        ("when @1 is 15 m away", Within(1, 7, metres=15.0)),
        ("once @4 has stopped", Stopped(4)),
        ("when @4 comes to a halt", Stopped(4)),
        ("once @4 has passed", Passed(4, 7)),
        ("after @4 goes past @9", Passed(4, 9)),
        ("then", AfterDone(3)),
        ("then ... 2 s later", AfterDone(3, 2.0)),
    ],
)  # fmt: skip
def test_timing_words_read_as_a_trigger(words, expected):
    assert trigger_of(words, agent=7, previous=3) == expected


@pytest.mark.parametrize(
    ("words", "previous", "reason"),
    [
        ("eventually", 3, "'eventually' is not a start LangTraj reads"),
        ("within 3 s", 3, "'within 3 s' is not a start LangTraj reads"),
        ("after @4 turns left", 3, "read as a sequence; ask that behaviour in a clause of its own"),
        ("after 2 s ... when @1 is within 20 m", 3, "says more than one when"),
        ("then", None, "'then' follows no clause of another agent"),
        ("when @7 is within 20 m", 3, "names @7 twice"),
        ("when @1 is within 0 m of @2", 3, "must be above 0"),
    ],
)
def test_a_start_it_cannot_read_is_refused_with_why(words, previous, reason):
    with pytest.raises(ValueError, match=reason):
        trigger_of(words, agent=7, previous=previous)


def _road(ego_x: float, lead_x: float, lead_speed: float = 10.0):
    """A scene on two lanes: @1 at `ego_x` and @2 at `lead_x` ahead in the same lane, both eastbound (@1 at
    10 m/s, @2 at `lead_speed`), as they are at the current step."""
    t = np.arange(91)[:, None] * 0.1
    ego = (AgentType.VEHICLE, np.hstack([ego_x + 10.0 * (t - 1.0), 0 * t]), np.zeros(91))
    lead = (AgentType.VEHICLE, np.hstack([lead_x + lead_speed * (t - 1.0), 0 * t]), np.zeros(91))
    s = scene(two_lane_road(), ego, lead)
    states = s.agents.states.copy()
    states[0, :, 4], states[1, :, 4] = 10.0, lead_speed
    return replace(s, agents=replace(s.agents, states=states))


def test_a_distance_is_bumper_to_bumper_and_a_headway_at_the_subjects_speed():
    near, far = _road(0.0, 24.0), _road(0.0, 25.0)  # centres 24 and 25 m apart, cars 4.5 m long: gaps 19.5, 20.5
    within = Within(1, 2, metres=20.0)
    assert within.holds(Now(near, 0.0)) and not within.holds(Now(far, 0.0))
    assert within.measured(Now(far, 0.0)) == "@1 20 m from @2"  # rounded: 20.5
    headway = Within(1, 2, seconds=2.0)  # 2 s at 10 m/s: 20 m
    assert headway.holds(Now(near, 0.0)) and not headway.holds(Now(far, 0.0))


def test_a_time_a_stop_a_pass_and_a_sequence_hold_when_they_should():
    s = _road(0.0, 24.0, lead_speed=0.0)
    assert not AtTime(3.0).holds(Now(s, 2.9 - 0.1)) and AtTime(3.0).holds(Now(s, 2.96))
    assert Stopped(2).holds(Now(s, 0.0)) and not Stopped(1).holds(Now(s, 0.0))
    assert not Passed(1, 2).holds(Now(s, 0.0)) and Passed(2, 1).holds(Now(s, 0.0))
    assert not AfterDone(2).holds(Now(s, 1.0)) and AfterDone(2).holds(Now(s, 1.0, {2: 0.5}))
    assert not AfterDone(2, 2.0).holds(Now(s, 1.0, {2: 0.5})) and AfterDone(2, 2.0).holds(Now(s, 2.5, {2: 0.5}))
    assert not Within(1, 99, metres=50.0).holds(Now(s, 0.0))  # an agent not in the scene: never
