"""When a behaviour staged on the ego's live state may start (`BehaviourKind.ready`), and a prompt's own trigger
starting a braking lead at once (`BehaviourKind.at_trigger`); which readings are staged so (`sim.prompts.
on_live_state`)."""

from __future__ import annotations

import numpy as np

from langtraj.interdrive.behaviour import Behaviour
from langtraj.interdrive.behaviours import kind
from langtraj.interdrive.behaviours.scripts import Braking
from langtraj.interdrive.reader import read_clauses
from langtraj.interdrive.targets import BehaviourTarget
from langtraj.interdrive.triggers import WhenReady
from langtraj.sim.prompts import on_live_state

PATH = np.stack([np.linspace(0, 100, 101), np.zeros(101)], axis=1)


def _cut_in(speed: float, current: float, other_speed: float) -> BehaviourTarget:
    return BehaviourTarget(7, Behaviour.CUT_IN, PATH, "", speed=speed, current_speed=current, other_id=1,
                           other_speed=other_speed, lead_m=14.5, settled_s=4.0)  # fmt: skip


def test_a_cut_in_starts_at_once_its_script_letting_the_other_come_up_but_never_cuts_in_on_a_standing_car():
    assert kind("cut_in").ready(_cut_in(speed=11.0, current=12.0, other_speed=12.0)) is None
    assert kind("cut_in").ready(_cut_in(speed=15.0, current=12.0, other_speed=12.0)) is None  # it speeds up
    assert kind("cut_in").ready(_cut_in(speed=6.0, current=16.0, other_speed=12.0)) is None  # it drops back
    # ... but `suggest` offers no cut-in that must first drop back hard
    assert kind("cut_in").natural(_cut_in(speed=11.0, current=12.0, other_speed=12.0)) is None
    slow = kind("cut_in").natural(_cut_in(speed=6.0, current=16.0, other_speed=12.0))
    assert slow == "it would slow from 16.0 to 6.0 m/s for @1 to come up"
    assert kind("overtake_cut_in").natural(_cut_in(speed=6.0, current=16.0, other_speed=12.0)) == slow
    # an overtaker 6 m/s faster than the other passes at its own speed and settles at the other's: natural; one 22 m/s
    # faster would shed them all to settle in front of it, and passes instead
    assert kind("overtake_cut_in").natural(_cut_in(speed=18.0, current=18.0, other_speed=12.0)) is None
    assert kind("overtake_cut_in").natural(_cut_in(speed=22.0, current=22.0, other_speed=12.0)) is None  # 10 in 3 s
    passing = kind("overtake_cut_in").natural(_cut_in(speed=29.0, current=29.0, other_speed=7.0))
    assert passing == "it would slow from 29.0 to 7.0 m/s to settle in front of @1: a pass, not a cut-in"
    standing = kind("cut_in").ready(_cut_in(speed=1.0, current=1.0, other_speed=0.1))
    assert standing == "@1 drives at 0.1 m/s (a cut-in needs 3 or more)"


def test_a_braking_lead_waits_for_its_follower_within_3_s_and_a_prompts_trigger_starts_it_at_once():
    lead = BehaviourTarget(7, Behaviour.BRAKE_HARD, PATH, "", speed=0.0, current_speed=12.0, other_id=1,
                           other_speed=10.0, deceleration=4.0, settled_s=4.0, other_gap_m=25.0)  # fmt: skip
    assert kind("brake_hard").ready(lead) is None  # 2.5 s
    far = BehaviourTarget(**{**lead.__dict__, "other_gap_m": 45.0})
    assert kind("brake_hard").ready(far) == "@1 is 45 m behind at 10.0 m/s (4.5 s; it brakes within 3 s)"
    assert kind("brake_hard").script(lead) == Braking(1.0, 4.0)
    assert kind("brake_hard").script(kind("brake_hard").at_trigger(lead)) == Braking(0.0, 4.0)
    assert kind("cut_in").at_trigger(_cut_in(11.0, 12.0, 12.0)) == _cut_in(11.0, 12.0, 12.0)  # unchanged


def test_behaviours_put_in_an_external_agents_path_are_staged_on_its_live_state():
    (cut,) = read_clauses("@7 cuts in front of @1")
    assert on_live_state(cut, external={1}).trigger == WhenReady()
    assert on_live_state(cut, external=set()) is cut  # toward an agent the model drives: from the start, as before
    (timed,) = read_clauses("@7 cuts in front of @1 after 3 s")
    assert on_live_state(timed, external={1}) is timed  # its own trigger
    (follow,) = read_clauses("@7 follows @1")
    assert on_live_state(follow, external={1}) is follow  # not in the ego's path
