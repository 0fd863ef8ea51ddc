"""The series a job's page plots for its prompted agents: speed as the adherence checker judges it (`rollout_scenario`)
over the history and each rollout, and the distance to the prompt's target, along its path (negative once past the
point) or straight without one; agents without a target, or not in the rollouts, say so."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scenario_builders import make_scenario

from langtraj.metrics.instruction_following import rollout_scenario
from langtraj.rollouts.container import Rollouts
from langtraj.scenario.io import read_scenario
from langtraj.scenario.model import Scenario
from langtraj.sim.failures import log_rollouts
from langtraj.studio.series import prompted_series

AHEAD_M = 20.0
"""How far along the hand-built path its goal lies past the agent's current position."""
STEP_M = 0.3
"""How far the hand-built rollout moves the agent along the path each step (3 m/s)."""


@pytest.fixture(scope="module")
def womd(real_data_dir: Path) -> Scenario:
    return read_scenario(real_data_dir / "motion_data_one_scenario.tfrecord")


def _straight(scenario: Scenario, track: int, steps: int = 80) -> tuple[dict[str, Any], Rollouts]:
    """A target for `track` on a straight path along its logged heading through its current position (a point every
    2 m from 10 m behind it), the goal 20 m ahead; and one rollout moving it along that path 0.3 m a step."""
    row, c = scenario.agents.index_of(track), scenario.current_index
    here = scenario.agents.xy[row, c].astype(np.float64)
    heading = float(scenario.agents.heading[row, c])
    ahead = np.array([math.cos(heading), math.sin(heading)])
    path = here + np.arange(-10.0, 62.0, 2.0)[:, None] * ahead
    target = {
        "track_id": track,
        "behaviour": "turn_left",
        "path": np.round(path, 2).tolist(),
        "goal": [round(float(v), 2) for v in here + AHEAD_M * ahead],
        "stop": False,
        "conflict": None,
    }
    moved = here + STEP_M * np.arange(1, steps + 1)[:, None] * ahead
    shape = (1, 1, steps)
    rollouts = Rollouts(
        object_id=np.array([track]),
        x=moved[:, 0].reshape(shape),
        y=moved[:, 1].reshape(shape),
        z=np.zeros(shape),
        heading=np.full(shape, heading),
    )
    return target, rollouts


def test_speed_is_what_the_checker_judges_over_history_and_rollout(womd: Scenario) -> None:
    """Two rollouts: the logged future, and one that moves every agent 0.5 m further east each step."""
    log = log_rollouts(womd)
    drift = 0.5 * np.arange(1, log.num_steps + 1, dtype=np.float32)
    two = {k: np.concatenate([getattr(log, k)] * 2) for k in ("x", "y", "z", "heading")}
    two["x"][1] += drift
    rollouts = replace(log, **two, log_following_ids=None)
    ids = [int(i) for i in rollouts.object_id[:3]]
    series = prompted_series(womd, rollouts, [], ids)
    c, length = womd.current_index, womd.current_index + 1 + rollouts.num_steps
    assert set(series) == {str(i) for i in ids}
    for r in range(2):
        agents = rollout_scenario(womd, rollouts, r).agents
        for track in ids:
            speed = series[str(track)]["speed"][r]
            assert len(speed) == length
            row = agents.index_of(track)
            for step in (0, c // 2, c, c + 1, c + 40, length - 1):
                expected = round(float(agents.speed[row, step]), 2) if agents.valid[row, step] else None
                assert speed[step] == expected
    one = series[str(ids[0])]["speed"]
    assert one[0][: c + 1] == one[1][: c + 1] and one[0][c + 1 :] != one[1][c + 1 :]
    json.dumps(series, allow_nan=False)


def test_a_step_the_agent_is_not_valid_at_is_null() -> None:
    """The toy scene's track 27 appears at step 30: its history is all null, its rollout steps are not."""
    scenario = make_scenario()
    _, rollouts = _straight(scenario, 7)
    rollouts = replace(rollouts, object_id=np.array([27]))
    speed = prompted_series(scenario, rollouts, [], [27])["27"]["speed"][0]
    c = scenario.current_index
    assert speed[: c + 1] == [None] * (c + 1) and None not in speed[c + 1 :]


@pytest.mark.parametrize("scene", ["toy", "womd"])
def test_the_distance_along_the_path_falls_by_the_distance_travelled(scene: str, request) -> None:
    """The rollout moves the agent 0.3 m a step along its target's path: the distance to the goal is 20 m at the
    current step, falls by exactly what it travelled and goes negative once it is past the goal."""
    scenario = make_scenario() if scene == "toy" else request.getfixturevalue("womd")
    track = 7 if scene == "toy" else 1675
    target, rollouts = _straight(scenario, track)
    entry = prompted_series(scenario, rollouts, [target], [track])[str(track)]
    assert entry["goal"] == "the goal"
    (to_target,) = entry["to_target"]
    c = scenario.current_index
    assert len(to_target) == c + 1 + rollouts.num_steps
    assert to_target[c] == pytest.approx(AHEAD_M, abs=0.02)
    for k in (1, 10, 40, 66, 67, 80):
        assert to_target[c] - to_target[c + k] == pytest.approx(STEP_M * k, abs=0.02)
    assert to_target[c + 66] > 0 > to_target[c + 67]  # the goal at 20 m: passed between 19.8 and 20.1 m
    assert to_target[-1] == pytest.approx(AHEAD_M - STEP_M * 80, abs=0.02)


def test_without_a_path_the_distance_is_straight() -> None:
    """A target without a path: the straight-line distance to its point, which stays positive past it; the first of
    an agent's targets counts, and a point that is the conflict is said to be."""
    scenario = make_scenario()
    target, rollouts = _straight(scenario, 7)
    goal = np.array(target["goal"])
    bare = target | {"path": []}
    later = target | {"goal": [0.0, 0.0], "track_id": 7}
    (to_target,) = prompted_series(scenario, rollouts, [bare, later], [7])["7"]["to_target"]
    row, c = scenario.agents.index_of(7), scenario.current_index
    for step in (0, c):
        assert to_target[step] == round(float(np.hypot(*(scenario.agents.xy[row, step] - goal))), 2)
    for k in (1, 40, 80):
        here = np.array([rollouts.x[0, 0, k - 1], rollouts.y[0, 0, k - 1]], np.float64)
        assert to_target[c + k] == pytest.approx(float(np.hypot(*(here - goal))), abs=0.01)
    assert min(to_target) >= 0 and to_target[-1] == pytest.approx(STEP_M * 80 - AHEAD_M, abs=0.02)
    conflict = target | {"goal": None, "conflict": target["goal"]}
    entry = prompted_series(scenario, rollouts, [conflict], [7])["7"]
    assert entry["goal"] == "the conflict point"
    assert entry["to_target"][0][c] == pytest.approx(AHEAD_M, abs=0.02)
    stop = target | {"stop": True}
    assert prompted_series(scenario, rollouts, [stop], [7])["7"]["goal"] == "the stop point"


def test_an_agent_without_a_target_has_no_distance() -> None:
    """No target for the agent, or one with neither a goal nor a conflict point: its speed alone."""
    scenario = make_scenario()
    target, rollouts = _straight(scenario, 7)
    for targets in ([], [target | {"track_id": 17}], [target | {"goal": None, "conflict": None}]):
        entry = prompted_series(scenario, rollouts, targets, [7])["7"]
        assert entry["to_target"] is None and entry["goal"] is None
        assert len(entry["speed"]) == 1 and len(entry["speed"][0]) == scenario.current_index + 81


def test_only_rollout_agents_are_plotted_over_the_steps_the_scene_has() -> None:
    """Ids the rollouts do not move (in the scene or not) are left out, a repeated one counts once; a scene logging
    fewer than 80 steps after its current one cuts the rollout there, as `rollout_scenario` does."""
    scenario = make_scenario()
    target, rollouts = _straight(scenario, 7)
    series = prompted_series(scenario, rollouts, [target], [17, 7, 999, 7])
    assert list(series) == ["7"]
    assert prompted_series(scenario, rollouts, [target], [17, 999]) == {}
    short = make_scenario(num_steps=50)
    (speed,) = prompted_series(short, rollouts, [target], [7])["7"]["speed"]
    assert len(speed) == 50
