"""`langtraj simulate` warns about a typed prompt asking for a turn or lane change the map does not allow, records
the warning in the summary, and simulates all the same; the warning is about the prompt as the reader reads it (the
reading that steers), asked of the map index the simulation steers by."""

from __future__ import annotations

import json

import numpy as np
from interdrive.test_counterfactual import LEFT_LANE_STRAIGHT, RIGHT_LANE_RIGHT, drive, four_way
from interdrive.test_heuristics import scene

from langtraj.cli.main import main
from langtraj.roads import MapIndex
from langtraj.rollouts.container import Rollouts
from langtraj.scenario.io import write_scenarios
from langtraj.sim.config import ALL_LEVERS
from langtraj.sim.prompts import prompt_steering, read_prompts

ORIGIN = (0.0, 0.0, 0.0)
LEFT_TURN_WARNING = "@2 cannot turn left: no left turn from its lane at the next junction (it allows: right turn)"


def _junction_scene():
    """Car 1 in the left lane (left turn and straight on), car 2 in the right lane, which allows a right turn only."""
    return scene(four_way(right_lane_exits=(14,)), drive(LEFT_LANE_STRAIGHT), drive(RIGHT_LANE_RIGHT))


def _warnings(s, texts: list[str]) -> list[str]:
    rows = np.arange(s.num_agents)
    return list(prompt_steering(s, read_prompts(texts), rows, ORIGIN, ALL_LEVERS, MapIndex.build(s.road_map)).warnings)


def test_prompt_warnings_name_each_agent_and_manoeuvre_the_map_does_not_allow():
    s = _junction_scene()
    assert _warnings(s, []) == []
    assert _warnings(s, ["@2 turns left", "@1 turns left"]) == [LEFT_TURN_WARNING]
    assert _warnings(s, ["@2 turns right and speeds up"]) == []  # two behaviours: not read, not warned about
    assert _warnings(s, ["@1 yields to @2"]) == []  # a pair behaviour is not a map manoeuvre
    assert _warnings(s, ["@1 changes lanes to the left"]) == [
        "@1 cannot change lanes to the left: no lane on its left along its road (within 64 m)"
    ]


def test_the_warning_is_about_the_agent_and_behaviour_the_prompt_steers():
    # The reader reads @2 as the one asked to turn left, though @1 is named first: the steering and the warning
    # are both about @2.
    s = _junction_scene()
    steering = prompt_steering(s, read_prompts(["After @1 passes, @2 turns left"]), np.arange(2), ORIGIN, ALL_LEVERS)
    assert steering.readings[0].agent == 2 and steering.asks[0].track_id == 2
    assert list(steering.warnings) == [LEFT_TURN_WARNING]


def test_simulate_warns_on_stderr_records_the_warning_and_still_runs(tiny_run, tmp_path, capsys, monkeypatch):
    checkpoint, _ = tiny_run
    builds = []
    build = MapIndex.build
    monkeypatch.setattr(MapIndex, "build", lambda *a, **k: builds.append(1) or build(*a, **k))
    scenes = tmp_path / "junction.tfrecord"
    write_scenarios(scenes, [_junction_scene()])
    out = tmp_path / "sim"
    fast = ["--rollouts", "1", "--candidates", "1", "--steps", "2", "--replan-s", "4", "--no-video"]
    code = main(["simulate", str(scenes), "--checkpoint", str(checkpoint), *fast, "--prompt", "@2 turns left",
                 "--prompt", "@1 goes straight", "--out", str(out)])  # fmt: skip
    captured = capsys.readouterr()
    assert code == 0, captured.err
    assert [line for line in captured.err.splitlines() if line.startswith("warning:")] == [
        f"warning: {LEFT_TURN_WARNING}"
    ]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["prompt_warnings"] == [LEFT_TURN_WARNING] and summary["prompted_ids"] == [2, 1]
    assert Rollouts.load(out / "rollouts.npz").x.shape == (1, 2, 80)
    assert len(builds) == 1  # one map index for the warnings, the targets and the judge

    quiet = tmp_path / "quiet"
    code = main(["simulate", str(scenes), "--checkpoint", str(checkpoint), *fast, "--prompt", "@2 turns right",
                 "--out", str(quiet)])  # fmt: skip
    assert code == 0 and "warning:" not in capsys.readouterr().err
    assert json.loads((quiet / "summary.json").read_text())["prompt_warnings"] == []
