"""Whether an episode's scenario happened: each prompt judged on the played scene by the labelers, and a suite
episode whose prompt was not followed reported as `not_happened` (not a pass) in results.json, report.md and JUnit."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from dataclasses import replace

import numpy as np
from scenario_builders import two_lane_road

from langtraj.suites import RunOptions, load_suite, run_suite
from langtraj.suites.happened import judge_prompts, not_happened
from suites.conftest import write_suite
from suites.fakes import FAKE_ENV, write_scene


def _speeding_up_scene():
    """Car 2 accelerates at 2 m/s^2 from the current step on; car 1 keeps 10 m/s."""
    scene = two_lane_road([(0.0, 0.0, 10.0), (30.0, 3.5, 10.0)])
    states = scene.agents.states.copy()
    t = np.clip(np.arange(scene.num_steps) - scene.current_index, 0, None) * 0.1
    states[1, :, 0] = states[1, :, 0] + t**2  # + a t^2 / 2 with a = 2
    states[1, :, 4] = 10.0 + 2.0 * t
    return replace(scene, agents=replace(scene.agents, states=states))


def test_prompts_are_judged_on_the_played_scene():
    verdicts = judge_prompts(_speeding_up_scene(), ["@2 speeds up", "@1 speeds up", "@2 dances", "@9 stops"])
    assert [v.followed for v in verdicts] == [True, False, None, None]
    assert verdicts[0].reading == 'read as: @2 speed_up ("speeds up")' and verdicts[0].why is None
    assert verdicts[2].why.startswith("not read") and verdicts[3].why == "@9 not in the scene"
    assert not_happened(verdicts) == [
        "scenario did not happen: '@1 speeds up' (read as: @1 speed_up (\"speeds up\")) not followed"
    ]


def test_a_case_whose_prompt_did_not_happen_is_not_a_pass(tmp_path):
    write_scene(tmp_path, "good")
    path = write_suite(
        tmp_path,
        [
            {"name": "quiet", "scenario": "good.json"},
            {"name": "turn", "scenario": "good.json", "prompts": ["@7 turns left"]},  # the fake's car 7 drives on
        ],
    )
    options = RunOptions(out=tmp_path / "out", planner="suites.fakes:GoodPlanner", env=FAKE_ENV, video=False)
    results = run_suite(load_suite(path), options)
    assert results.case_statuses() == {"quiet": "pass", "turn": "not_happened"} and not results.passed
    saved = json.loads((options.out / "results.json").read_text())
    turn = saved["episodes"][1]
    assert turn["status"] == "not_happened" and turn["reasons"][0].startswith("scenario did not happen: '@7 turns")
    assert turn["prompts"][0]["followed"] is False and saved["episodes"][0]["prompts"] == []
    assert saved["summary"]["not_happened"] == 1 and saved["summary"]["cases_not_happened"] == 1
    skipped = ET.parse(options.out / "junit.xml").getroot().find("testsuite/testcase[@name='turn[seed0]']/skipped")
    assert skipped.get("type") == "not_happened"
    report = (options.out / "report.md").read_text()
    assert "1 whose scenario did not happen" in report and "## turn: NOT_HAPPENED" in report
    assert '| @7 turns left | read as: @7 turn_left ("turns left") | NOT FOLLOWED |' in report
