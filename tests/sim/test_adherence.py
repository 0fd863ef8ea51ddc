"""Adherence of candidates (`sim.adherence`): on constructed trajectories that do and do not follow a prompt, the
candidate judge that selection uses agrees with the judge that scores instruction following."""

from __future__ import annotations

import numpy as np
import pytest
from interdrive.test_counterfactual import two_lane_road, x_junction_yield
from interdrive.test_ground_truth import VEH, straight
from interdrive.test_ground_truth import scene as track_scene
from interdrive.test_heuristics import TIME, scene

from langtraj.interdrive.adherence import AdherenceChecker
from langtraj.interdrive.behaviour import Behaviour
from langtraj.interdrive.counterfactual import make_alternative
from langtraj.interdrive.mapindex import MapIndex
from langtraj.metrics.instruction_following import judge_rollouts
from langtraj.rollouts.container import Rollouts
from langtraj.scenario import AgentType, Scenario
from langtraj.sim.adherence import Ask, CandidateJudge
from langtraj.sim.world import SimWorld


def _eastbound(speeds: np.ndarray, y: np.ndarray | float = 0.0) -> tuple[AgentType, np.ndarray, np.ndarray]:
    x = np.concatenate([[0.0], np.cumsum(speeds[:-1] * 0.1)])
    y = np.broadcast_to(np.asarray(y, np.float64), x.shape)
    return AgentType.VEHICLE, np.stack([x, y], 1), np.arctan2(np.gradient(y), np.gradient(x))


def _future(s: Scenario, row: int) -> np.ndarray:
    """The logged future of `row` as poses [T, 4] (x, y, heading, speed)."""
    c = s.current_index
    st = s.agents.states[row, c + 1 :].astype(np.float64)
    xy = s.agents.states[row, c:, :2].astype(np.float64)
    speed = np.linalg.norm(np.diff(xy, axis=0), axis=1) / 0.1
    return np.concatenate([st[:, :2], st[:, 3:4], speed[:, None]], 1)


def _verdicts(candidates: list[Scenario], ask: Ask, driven: list[int]) -> tuple[list[bool], list[bool]]:
    """(candidate judge, instruction-following judge) verdicts of each candidate scene: its logged future is the
    candidate of every driven row."""
    base = candidates[0]
    world = SimWorld(base, np.array(driven), 1)
    plans = np.stack([np.stack([_future(c, row) for row in driven])[None] for c in candidates])  # [M, 1, A, T, 4]
    judge = CandidateJudge(world, [ask], MapIndex.build(base.road_map))
    selection = (~judge.misses([0], world.start, plans)[0, :, 0]).tolist()
    checker = AdherenceChecker.build(base)
    alternative = make_alternative(ask.behaviour, ask.track_id, frozenset(), ask.other_id)
    scoring = []
    for c in candidates:
        rows = list(range(c.num_agents))
        futures = np.stack([_future(c, r) for r in rows])
        rollouts = Rollouts(
            object_id=c.agents.ids[rows],
            x=futures[None, ..., 0].astype(np.float32),
            y=futures[None, ..., 1].astype(np.float32),
            z=np.zeros((1, len(rows), futures.shape[1]), np.float32),
            heading=futures[None, ..., 2].astype(np.float32),
            scenario_id=c.scenario_id,
        )
        (verdict,) = judge_rollouts(base, rollouts, [alternative], checker=checker)
        scoring.append(verdict.followed)
    return selection, scoring


def test_a_stop_and_a_drive_on_are_judged_alike_by_selection_and_scoring():
    stops = np.where(TIME < 2.0, 10.0, np.maximum(10.0 - 4.0 * (TIME - 2.0), 0.0))
    candidates = [
        scene(two_lane_road(), _eastbound(stops)),
        scene(two_lane_road(), _eastbound(np.full_like(TIME, 10.0))),
    ]
    selection, scoring = _verdicts(candidates, Ask(1, 0, 0, Behaviour.STOP), [0])
    assert selection == scoring == [True, False]


def test_a_left_lane_change_and_keeping_the_lane_are_judged_alike():
    blend = np.clip((TIME - 3.0) / 3.0, 0.0, 1.0)
    change = 3.5 * (1 - np.cos(np.pi * blend)) / 2
    speeds = np.full_like(TIME, 10.0)
    candidates = [scene(two_lane_road(), _eastbound(speeds, change)), scene(two_lane_road(), _eastbound(speeds))]
    selection, scoring = _verdicts(candidates, Ask(1, 0, 0, Behaviour.LANE_CHANGE_LEFT), [0])
    assert selection == scoring == [True, False]


@pytest.mark.parametrize(
    ("behaviour", "expected"), [(Behaviour.YIELD, [True, False]), (Behaviour.GO_FIRST, [False, True])]
)
def test_waiting_for_a_crossing_car_and_going_before_it_are_judged_alike(behaviour, expected):
    waits = x_junction_yield()  # car 1 waits west of the crossing while car 2 crosses northbound
    # ... or car 1 crosses while car 2 waits south of the crossing
    held = np.where(np.arange(len(TIME)) < 50, 0.0, 5.0)
    goes = track_scene({1: (VEH, straight(-8, 0, 0, 6.0)), 2: (VEH, straight(0, -8, np.pi / 2, held))})
    ask = Ask(1, 0, 0, behaviour, other_id=2, other_row=1, other_slot=1)
    verdicts = [_verdicts([candidate], ask, [0, 1]) for candidate in (waits, goes)]  # histories differ: one each
    selection = [v[0][0] for v in verdicts]
    scoring = [v[1][0] for v in verdicts]
    assert selection == scoring == expected


def test_the_copies_of_a_prompted_agent_form_a_valid_scene_whatever_its_self_driving_car():
    from dataclasses import replace

    s = replace(scene(two_lane_road(), _eastbound(np.full_like(TIME, 10.0)), _eastbound(np.full_like(TIME, 5.0), 3.5)))
    s = replace(s, sdc_index=1)  # a WOMD scene names its self-driving car; the copies scene has other rows
    world = SimWorld(s, np.array([0, 1]), 1)
    plans = np.stack([np.stack([_future(s, 0), _future(s, 1)])[None]])
    judge = CandidateJudge(world, [Ask(1, 0, 0, Behaviour.STOP)], MapIndex.build(s.road_map))
    assert judge.misses([0], world.start, plans).tolist() == [[[True]]]
