"""Whether an episode's scenario happened: each prompt judged on the played scene by the labelers (and, for the
safety-critical pair behaviours, by its numbers too), and a suite episode whose prompt was not followed reported as
`not_happened` (not a pass) in results.json, report.md and JUnit, with the numbers asked beside those realised."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from dataclasses import replace

import numpy as np
import pytest
from scenario_builders import two_lane_road

from langtraj.suites import RunOptions, load_suite, run_suite
from langtraj.suites.episode import EpisodeResult
from langtraj.suites.happened import PromptVerdict, judge_prompts, not_happened
from langtraj.suites.junit import junit_tree
from langtraj.suites.report import render_report, sweep_values
from langtraj.suites.results import SuiteResults
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


def _cut_in_scene(gap: float):
    """On the two-lane road, car 2 changes from the left lane into car 1's, `gap` m ahead bumper to bumper (both at
    10 m/s), from 1 s over 3 s: a cut-in the labelers see, with a gap the numbers read."""
    scene = two_lane_road([(0.0, 0.0, 10.0), (4.5 + gap, 3.5, 10.0)])
    states = scene.agents.states.copy()
    t = (np.arange(scene.num_steps) - scene.current_index) * 0.1
    r = np.clip((t - 1.0) / 3.0, 0.0, 1.0)
    states[1, :, 1] = 3.5 * (1.0 - (3 * r**2 - 2 * r**3))
    states[1, :, 5] = np.gradient(states[1, :, 1], 0.1)
    states[1, :, 3] = np.arctan2(np.gradient(states[1, :, 1]), np.gradient(states[1, :, 0]))
    return replace(scene, agents=replace(scene.agents, states=states))


def test_a_cut_in_is_followed_only_when_its_numbers_are_met_too():
    texts = ["@2 cuts in front of @1 with a 15 m gap", "@2 cuts in front of @1 with an 8 m gap", "@1 speeds up"]
    missed, met, plain = judge_prompts(_cut_in_scene(7.5), texts)
    assert missed.followed is False and missed.why == "gap 7.5 m done, 15 m asked (+-3 m)"
    assert [m.name for m in missed.measures] == ["gap", "time to settle"]
    assert missed.measures[0].asked == 15.0 and missed.measures[0].realised == pytest.approx(7.5, abs=0.05)
    assert met.followed is True and met.why is None and met.measures[0].asked == 8.0
    assert plain.measures == [] and plain.to_json()["measures"] == []
    assert missed.to_json()["measures"][0] == {
        "name": "gap",
        "unit": "m",
        "asked": 15.0,
        "realised": 7.5,
        "tolerance": 3.0,
        "ok": False,
        "describe": "gap 15 m asked, 7.5 m done (+-3 m)",
    }
    assert not_happened([missed])[0].endswith("not followed: gap 7.5 m done, 15 m asked (+-3 m)")
    (default,) = judge_prompts(_cut_in_scene(15.0), ["@2 cuts in front of @1"])  # 10 m when no gap is asked
    assert default.followed is False and default.why == "gap 15 m done, 10 m asked (+-3 m)"
    (unseen,) = judge_prompts(_cut_in_scene(30.0), ["@2 cuts in front of @1 with a 30 m gap"])
    assert unseen.followed is False and unseen.why.startswith("the labelers did not see it, though by its numbers")


def test_a_swept_cut_in_shows_asked_and_realised_side_by_side(tmp_path):
    """The runner end to end (the fake env's toy scene: 37 never leaves the lane beside 7), then the reports of
    episodes with realised numbers."""
    write_scene(tmp_path, "good")
    case = {"name": "cut", "scenario": "good.json", "prompts": ["@37 cuts in front of @7 with a ${gap_m} m gap"]}
    path = write_suite(tmp_path, [{**case, "sweep": {"gap_m": [5, 15]}}])
    options = RunOptions(out=tmp_path / "out", planner="suites.fakes:GoodPlanner", env=FAKE_ENV, video=False)
    suite = load_suite(path)
    results = run_suite(suite, options)
    assert results.case_statuses() == {"cut.gap_m-5": "not_happened", "cut.gap_m-15": "not_happened"}
    saved = json.loads((options.out / "results.json").read_text())
    (row, _) = saved["cases"][1]["measures"]
    assert row["measure"] == "gap" and row["asked"] == 15.0 and row["seeds"][0]["realised"] is None
    assert "never settled in @7's path" in saved["episodes"][0]["reasons"][0]

    fresh = SuiteResults(suite, tmp_path / "again", planner="idm", planner_cmd=None, step_timeout=5.0)
    for name, asked, done, status in (("cut.gap_m-5", 5.0, 2.5, "pass"), ("cut.gap_m-15", 15.0, 2.5, "not_happened")):
        ok = abs(done - asked) <= 3.0
        measures = [
            {"name": "gap", "unit": "m", "asked": asked, "realised": done, "tolerance": 3.0, "ok": ok},
            {"name": "time to settle", "unit": "s", "asked": None, "realised": 3.2, "tolerance": None, "ok": None},
        ]
        why = None if ok else f"gap 2.5 m done, {asked:g} m asked (+-3 m)"
        prompt = {"text": f"@37 cuts in front of @7 with a {asked:g} m gap", "reading": "read as: @37 cut_in @7"}
        prompt |= {"behaviour": "cut_in", "agent": 37, "other": 7, "followed": ok, "why": why, "measures": measures}
        fresh.add(EpisodeResult(case=name, seed=0, status=status, prompts=[prompt], figures={}))
    report = render_report(fresh)
    assert "| @37 cuts in front of @7 with a 15 m gap | gap | 15 m +-3 m | 2.5 m (missed) |" in report
    assert "| @37 cuts in front of @7 with a 5 m gap | time to settle | - | 3.2 s |" in report
    assert "NOT FOLLOWED: gap 2.5 m done, 15 m asked (+-3 m)" in report
    assert "### Sweep cases[0] (gap_m)" in report
    assert "| 5 | 0 | @37 gap | 5 m +-3 m | 2.5 m | yes | pass |" in report
    assert "| 15 | 0 | @37 gap | 15 m +-3 m | 2.5 m | no | NOT HAPPENED |" in report
    out = junit_tree(fresh).getroot().find("testsuite/testcase[@name='cut.gap_m-15[seed0]']/system-out").text
    assert out.splitlines()[1] == (
        "@37 cuts in front of @7 with a 15 m gap: gap 15 m asked, 2.5 m done (+-3 m) MISSED; time to settle 3.2 s done"
    )


def test_sweep_values_are_read_from_the_case_names():
    assert sweep_values(["cut-in.gap_m-5", "cut-in.gap_m-10"]) == [{"gap_m": "5"}, {"gap_m": "10"}]
    two = sweep_values(["a.b.g-0.5.d-1", "a.b.g-2.d-1"])
    assert two == [{"g": "0.5", "d": "1"}, {"g": "2", "d": "1"}]
    assert sweep_values(["plain", "other"]) is None


def test_a_prompt_the_scene_ruled_out_reads_apart_from_one_not_followed():
    verdict = PromptVerdict("@5 brakes hard in front of @1", "read as: @5 brake_hard @1", "brake_hard", 5, 1, False)
    warning = "@5 cannot brake hard in front of @1: it is too slow to brake hard at 4 m/s^2 (0.0 m/s; at least 4)"
    (ruled_out,) = not_happened([verdict], [warning, "@7 cannot turn left: no junction"])
    assert ruled_out.startswith("scenario could not happen: '@5 brakes hard in front of @1'") and warning in ruled_out
    (plain,) = not_happened([verdict], ["@7 cannot turn left: no junction"])
    assert plain.startswith("scenario did not happen: ") and plain.endswith(" not followed")
