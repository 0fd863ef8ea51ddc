"""Behaviours staged at their trigger (`sim.staging`) in closed loop with the shipped checkpoint, on a constructed
junction: a stop asked "after 3 s" starts at the replan at 3 s with its target derived from where the car is then,
the car drives on as unprompted before it, and the judge reads the manoeuvre from that step on (the fixtures:
`conftest.py`)."""

from __future__ import annotations

import numpy as np
from interdrive.test_counterfactual import two_lane_road
from interdrive.test_heuristics import TIME, scene

from langtraj.interdrive.adherence import AdherenceChecker
from langtraj.interdrive.behaviours.verdict import Start, judge_reading
from langtraj.interdrive.dataset import PromptEntry
from langtraj.interdrive.prompts import parse_user_prompt
from langtraj.interdrive.reader import read_clauses
from langtraj.scenario.types import AgentType, StateField
from langtraj.sim.config import PromptLevers, SimConfig, SimRequest
from langtraj.sim.engine import simulate
from langtraj.sim.policies import LangTrajPolicy
from langtraj.sim.staging import starts_of

LEVERS = PromptLevers(text=True, guidance=True, selection=True)


def _run(loaded, s, text: str | None, ids=(1, 2)):
    model, data = loaded
    prompt = None if text is None else PromptEntry.of(parse_user_prompt(text, list(ids)))
    policy = LangTrajPolicy(model, data, SimRequest(candidates=2, levers=LEVERS, selector="first"), prompt=prompt)
    return simulate(s, policy, SimConfig(rollouts=2, replan_s=1.0, seed=0))


def _speeds(result, s) -> np.ndarray:
    """@1's speed [R, T] over the simulated steps."""
    states = result.world.states[:, 0, s.current_index + 1 :]
    return np.hypot(states[..., StateField.VX], states[..., StateField.VY])


def test_a_stop_after_3_s_starts_at_3_s_from_where_the_car_is_then(loaded, junction):
    free, at_once = _run(loaded, junction, None), _run(loaded, junction, "@1 stops")
    staged = _run(loaded, junction, "@1 stops after 3 s")
    (entry,) = staged.report["prompt"]["staged"]
    assert entry["agent"] == 1 and entry["trigger"] == "from 3 s"
    assert [r["started_s"] for r in entry["rollouts"]] == [3.0, 3.0]
    starts = starts_of(staged.report)
    assert starts[1] == Start(junction.current_index + 30, 3.0)
    early, late = slice(0, 25), slice(60, 80)
    v_free, v_now, v_staged = (_speeds(r, junction) for r in (free, at_once, staged))
    # before its start it does not begin to stop (as the stop asked at once does); after, it stops
    assert v_staged[:, early].mean() > v_now[:, early].mean() + 0.5
    assert v_staged[:, early].min() >= 0.8 * 6.0
    assert v_staged[:, late].mean() < 0.5 * v_free[:, late].mean()
    # judged from its start: followed, with when it started among the measures
    (reading,) = read_clauses("@1 stops after 3 s")
    played = staged.world.played(0)
    verdict = judge_reading(reading, played, AdherenceChecker.build(played, logged=False).facts(played), starts[1])
    assert verdict.followed is True and verdict.measures[0].name == "started" and verdict.measures[0].realised == 3.0


def test_a_start_that_never_holds_is_not_followed_and_says_why(junction):
    (reading,) = read_clauses("@1 stops when @2 is within 1 m of @1")
    verdict = judge_reading(reading, junction, frozenset(), Start(None, None, "its start never held: @2 9 m from @1"))
    assert verdict.followed is False and verdict.why == "it never started: its start never held: @2 9 m from @1"


def _eastbound(x: float, speed: float = 10.0):
    return AgentType.VEHICLE, np.stack([x + speed * TIME, np.zeros_like(TIME)], axis=1), np.zeros_like(TIME)


def test_a_scripted_brake_after_2_5_s_starts_between_replans_at_the_asked_deceleration(loaded):
    # @1 leads @2 by 15.5 m (bumpers) in one lane of a straight road at 10 m/s; replans are at whole seconds, the start
    # half-way. (25.5 m back, the model drifts @2 into the next lane before 2.5 s, where no braking lead is staged in
    # front of it: `brake_hard._on_their_way`.)
    lead = scene(two_lane_road(), _eastbound(20.0), _eastbound(0.0))
    result = _run(loaded, lead, "@1 brakes hard at 4 m/s^2 in front of @2 after 2.5 s")
    (entry,) = result.report["prompt"]["staged"]
    assert [r["started_s"] for r in entry["rollouts"]] == [2.5, 2.5], entry  # its step, not the next replan's
    speeds = _speeds(result, lead)  # [R, T]: T[k] is the speed at (k + 1) / 10 s
    drops = -np.diff(speeds, axis=1) / 0.1
    assert np.allclose(drops[:, 24:39], 4.0, atol=0.05)  # from 2.5 s at 4 m/s^2, executed at 10 Hz


def _lateral(result, s, slot: int) -> np.ndarray:
    """The agent in `slot`'s y [R, T] over the simulated steps."""
    return result.world.states[:, slot, s.current_index + 1 :, StateField.Y]


def test_a_cut_in_after_3_s_keeps_its_lead_in_its_own_lane_until_then_and_moves_across_after(loaded):
    # @1 beside @2 in the left lane of a straight road, 14.5 m ahead (the 10 m gap asked), both at 10 m/s
    beside = scene(two_lane_road(), (AgentType.VEHICLE, *_eastbound(14.5)[1:]), _eastbound(0.0))
    beside.agents.states[0, :, StateField.Y] = 3.5
    beside.agents.states[:, :, StateField.VX] = 10.0  # the scripts read the recorded velocity
    untimed = _run(loaded, beside, "@1 cuts in front of @2 with a 10 m gap")
    timed = _run(loaded, beside, "@1 cuts in front of @2 with a 10 m gap after 3 s")
    (entry,) = timed.report["prompt"]["staged"]
    assert [r["started_s"] for r in entry["rollouts"]] == [3.0, 3.0]
    entered = [np.flatnonzero(np.abs(y) < 1.75) for y in _lateral(timed, beside, 0)]
    assert all(e.size and 3.0 <= (e[0] + 1) / 10 <= 5.5 for e in entered)  # across from 3 s, not before
    early = _lateral(timed, beside, 0)[:, :29]
    assert np.abs(early - 3.5).max() < 0.7  # its own lane until then, placed at its lead (`CutIn.placed`)
    x = timed.world.states[:, :2, beside.current_index + 30, StateField.X]
    assert np.abs(x[:, 0] - x[:, 1] - 14.5).max() < 3.0
    first = [np.flatnonzero(np.abs(y) < 1.75) for y in _lateral(untimed, beside, 0)]
    assert all(f.size and (f[0] + 1) / 10 < 2.5 for f in first)  # untimed, it moves across at once


def _gap_at(result, s, step: int) -> np.ndarray:
    """The bumper gap between @1 and @2 [R] at simulated `step` (their centres less half of each length)."""
    states = result.world.states[:, :2, step]
    centres = np.hypot(*(states[:, 0, [StateField.X, StateField.Y]] - states[:, 1, [StateField.X, StateField.Y]]).T)
    return centres - 0.5 * states[:, :, StateField.LENGTH].sum(axis=1)


def test_a_braking_lead_when_its_follower_is_within_20_m_eases_off_until_it_is_and_brakes_there(loaded):
    # @1 leads @2 by 30 m (bumpers) in one lane at 10 m/s: at the same speed @2 would never come within 20 m
    lead = scene(two_lane_road(), _eastbound(34.5), _eastbound(0.0))
    lead.agents.states[:, :, StateField.VX] = 10.0
    result = _run(loaded, lead, "When @2 is within 20 m of @1, @1 brakes hard at 4 m/s^2 in front of @2")
    (entry,) = result.report["prompt"]["staged"]
    started = [r["started_s"] for r in entry["rollouts"]]
    assert all(s is not None and 1.0 <= s <= 6.5 for s in started), started
    for r, at in enumerate(started):
        step = lead.current_index + round(at / 0.1)
        assert 17.0 <= _gap_at(result, lead, step)[r] <= 20.0  # braking starts with @2 at the asked gap
        speeds = _speeds(result, lead)[r]
        assert speeds[: step - lead.current_index - 1].min() >= 5.9  # eased off no slower than it needs to brake
        drops = -np.diff(speeds[step - lead.current_index :]) / 0.1
        assert np.allclose(drops[:10], 4.0, atol=0.05)  # then at 4 m/s^2, at once
