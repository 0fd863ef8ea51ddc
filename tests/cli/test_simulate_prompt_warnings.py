"""`langtraj simulate` warns about a typed prompt asking for a turn or lane change the map does not allow, records
the warning in the summary, and simulates all the same; the warning is about the prompt as the reader reads it (the
reading that steers), asked of the map index the simulation steers by. Timing words the reader does not honour, a pair
behaviour with no second agent and an overtake alone are refused in one line instead (exit 2)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from interdrive.test_counterfactual import LEFT_LANE_STRAIGHT, RIGHT_LANE_RIGHT, drive, four_way
from interdrive.test_heuristics import scene

from langtraj.cli.main import main
from langtraj.errors import InputError
from langtraj.roads import MapIndex
from langtraj.rollouts.container import Rollouts
from langtraj.scenario.io import write_scenarios
from langtraj.sim.config import ALL_LEVERS
from langtraj.sim.prompt_checks import check_prompts
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
    # are both about @2, which starts once @1 has passed it (the map's verdict on a turn holds then too).
    s = _junction_scene()
    readings = read_prompts(["After @1 passes, @2 turns left"], strict=False)
    steering = prompt_steering(s, readings, np.arange(2), ORIGIN, ALL_LEVERS)
    assert steering.readings[0].agent == 2 and steering.asks[0].track_id == 2
    assert steering.readings[0].condition == "After @1 passes"
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


REFUSED = [
    ("@7 cuts in front of @17 eventually",
     "prompt '@7 cuts in front of @17 eventually': 'eventually' is not a start LangTraj reads (it reads 'after 3 s', "
     "'at 4 s', 'when @1 is within 20 m (or 2 s) of @7'"),
    ("@7 slows down within 3 s", "'within 3 s' is not a start LangTraj reads"),
    ("after @17 turns left, @7 goes first",
     "'after @17 turns left': a start after another agent's behaviour is read as a sequence; ask that behaviour in a "
     "clause of its own, then this one"),
    ("@7 cuts in front of @17 after 2 s when @17 is within 20 m",
     "'after 2 s ... when @17 is within 20 m' says more than one when"),
    ("@7 runs the red light",
     "clause '@7 runs the red light': run_red_light needs a second agent: name whose path it crosses, e.g. '@7 runs "
     "the red light across the path of @Y'"),
    ("@7 cuts in", "cut_in needs a second agent: name whom it cuts in front of, e.g. '@7 cuts in front of @Y'"),
    ("@7 overtakes @17",
     "clause '@7 overtakes @17' is not read: overtaking alone is not a behaviour LangTraj steers; say '@7 overtakes "
     "@17 and cuts in front of it'"),
]  # fmt: skip


@pytest.mark.parametrize(("text", "message"), REFUSED)
def test_timing_a_lone_pair_word_and_an_overtake_alone_are_one_line_errors(text, message):
    with pytest.raises(InputError, match=r"^prompt: ") as refused:
        read_prompts([text])
    assert message in str(refused.value) and "\n" not in str(refused.value)
    loose = read_prompts([text], strict=False)  # judging a played episode: kept on the reading, never refused
    if "start" in message or "when" in message:  # timing words: kept on the reading, named in its line
        assert any(r.condition and r.condition.split(" ... ")[0] in message for r in loose), loose
    else:  # a lone pair word, an overtake alone: not read, with the reason
        assert all(not r.read for r in loose) and any(r.reason for r in loose), loose


def test_one_agent_manoeuvre_then_stop_still_runs():
    (reading,) = read_prompts(["@2 turns left and then stops"])
    assert reading.then is not None and reading.condition == ""


def test_the_prompt_check_names_the_timing_not_the_ego_it_mentions():
    s = _junction_scene()  # the env's check: the ego named in a condition is no request to the ego
    (check,) = check_prompts(s, ["@2 slows down once @1 turns left"], ego=1, targets=False).prompts
    assert check.error is not None and "'once @1 turns left': a start after another agent's" in check.error
    (timed,) = check_prompts(s, ["when @1 is 20 m behind, @2 slows down"], ego=1, targets=False).prompts
    assert timed.error is None  # a start LangTraj reads: staged when @1 is within 20 m
    (asked,) = check_prompts(s, ["@1 slows down"], ego=1, targets=False).prompts
    assert asked.error == "'@1 slows down' asks something of the ego, which the planner drives"


@pytest.mark.parametrize(("text", "message"), REFUSED)
def test_simulate_refuses_them_in_one_line_with_exit_2(tiny_run, tmp_path, capsys, text, message):
    checkpoint, scenes = tiny_run  # tracks 7, 17, 37 and 47 are valid at the current step
    out = tmp_path / "sim"
    code = main(["simulate", str(scenes), "--checkpoint", str(checkpoint), "--out", str(out), "--prompt", text])
    err = capsys.readouterr().err
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1, err
    assert not out.exists()
