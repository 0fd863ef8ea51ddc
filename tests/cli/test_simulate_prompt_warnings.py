"""`langtraj simulate` warns about a typed prompt asking for a turn or lane change the map does not allow, records
the warning in the summary, and simulates all the same."""

from __future__ import annotations

import json

from interdrive.test_counterfactual import LEFT_LANE_STRAIGHT, RIGHT_LANE_RIGHT, drive, four_way
from interdrive.test_heuristics import scene

from langtraj.cli.main import main
from langtraj.rollouts.container import Rollouts
from langtraj.scenario.io import write_scenarios
from langtraj.sim.prompts import prompt_warnings

LEFT_TURN_WARNING = "@2 cannot turn left: no left turn from its lane at the next junction (it allows: right turn)"


def _junction_scene():
    """Car 1 in the left lane (left turn and straight on), car 2 in the right lane, which allows a right turn only."""
    return scene(four_way(right_lane_exits=(14,)), drive(LEFT_LANE_STRAIGHT), drive(RIGHT_LANE_RIGHT))


def test_prompt_warnings_name_each_agent_and_manoeuvre_the_map_does_not_allow():
    s = _junction_scene()
    assert prompt_warnings(s, []) == []
    assert prompt_warnings(s, ["@2 turns left", "@1 turns left"]) == [LEFT_TURN_WARNING]
    assert prompt_warnings(s, ["@2 turns right and speeds up"]) == []
    assert prompt_warnings(s, ["@1 changes lanes to the left"]) == [
        "@1 cannot change lanes to the left: no lane on its left along its road (within 64 m)"
    ]


def test_simulate_warns_on_stderr_records_the_warning_and_still_runs(tiny_run, tmp_path, capsys):
    checkpoint, _ = tiny_run
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

    quiet = tmp_path / "quiet"
    code = main(["simulate", str(scenes), "--checkpoint", str(checkpoint), *fast, "--prompt", "@2 turns right",
                 "--out", str(quiet)])  # fmt: skip
    assert code == 0 and "warning:" not in capsys.readouterr().err
    assert json.loads((quiet / "summary.json").read_text())["prompt_warnings"] == []
