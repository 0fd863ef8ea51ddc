"""The suite's pre-flight: every case checked against its scene as the env checks it at reset, before any episode
runs; a case refused is one line naming the suite file, the case's key, its name and the prompt."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from scenario_builders import two_lane_road

from langtraj.errors import InputError
from langtraj.scenario.io import write_scenarios
from langtraj.suites import RunOptions, load_suite, run_suite
from langtraj.suites.preflight import check_cases, refused
from suites.conftest import write_suite
from suites.fakes import FAKE_ENV, write_scene


@pytest.fixture
def road(tmp_path: Path) -> Path:
    """A straight two-lane road: the self-driving car @1 (the ego), @2 ahead of it, @3 in the next lane."""
    path = tmp_path / "road.pkl"
    write_scenarios(path, [two_lane_road([(0, 0, 10), (40, 0, 8), (0, 3.5, 10)])])  # @2 leaves room for a cut-in
    return path


def _error(tmp_path: Path, cases: list[dict]) -> str:
    suite = load_suite(write_suite(tmp_path, cases))
    with pytest.raises(InputError) as raised:
        check_cases(suite)
    text = str(raised.value)
    assert text.startswith(f"{suite.path}: ") and "\n" not in text, text
    return text[len(f"{suite.path}: ") :]


def test_cases_the_env_accepts_pass(tmp_path, road):
    cases = [
        {"name": "plain", "scenario": "road.pkl"},
        {"name": "lead", "scenario": "road.pkl", "prompts": ["@2 slows down"], "adversary": 3, "target": "ego"},
    ]
    check_cases(load_suite(write_suite(tmp_path, cases)))


@pytest.mark.parametrize(
    ("case", "message"),
    [
        (
            {"prompts": ["@2 slows down", "@9 brakes hard"]},
            "cases[1].prompts[1]: case bad, prompt '@9 brakes hard': unknown agent @9; the scene has agents 1, 2, 3",
        ),
        (
            {"prompts": ["@ego slows down"]},
            "cases[1].prompts[0]: case bad, prompt '@ego slows down': '@1 slows down' asks something of the ego, which "
            "the planner drives",
        ),
        ({"ego": 7}, "cases[1].ego: case bad: no agent @7 in scenario straight"),
        ({"adversary": 9, "target": "ego"}, "cases[1].adversary: case bad: @9 is not an agent of this scene"),
        ({"window": 3}, "cases[1].window: case bad: window 3 does not exist"),
        ({"index": 2}, "cases[1].scenario: case bad: "),
    ],
)
def test_a_case_the_env_would_refuse_is_one_line_naming_it(tmp_path, road, case, message):
    text = _error(tmp_path, [{"name": "good", "scenario": "road.pkl"}, {"name": "bad", "scenario": "road.pkl", **case}])
    assert text.startswith(message), text


def test_a_swept_case_is_named_by_its_place_in_the_file_and_its_own_name(tmp_path, road):
    cases = [
        {"name": "good", "scenario": "road.pkl", "sweep": {"who": [2, 3]}, "prompts": ["@${who} slows down"]},
        {"name": "lead", "scenario": "road.pkl", "sweep": {"who": [2, 5]}, "prompts": ["@${who} slows down"]},
    ]
    assert _error(tmp_path, cases).startswith("cases[1].prompts[0]: case lead.who-5, prompt '@5 slows down': ")


def test_another_env_is_checked_by_its_own_check_case_if_it_has_one(tmp_path):
    write_scene(tmp_path, "good", agents=[2, 3])
    suite = load_suite(write_suite(tmp_path, [{"name": "a", "scenario": "good.json", "prompts": ["@4 brakes"]}]))
    with pytest.raises(InputError, match=r"cases\[0\]\.prompts\[0\]: case a, prompt '@4 brakes': unknown agent @4"):
        check_cases(suite, FAKE_ENV)
    check_cases(suite, "suites.fakes:GoodPlanner")  # no check_case: nothing to check here


def test_a_refusal_by_the_sim_names_the_prompt_by_its_index_or_its_agent(tmp_path, road):
    cases = [{"name": "a", "scenario": "road.pkl", "prompts": ["@2 slows down", "@3 follows @ego"]}]
    suite = load_suite(write_suite(tmp_path, cases))
    by_index = refused(suite, 0, "prompts[1]: @3 is not valid", "prompts")
    assert str(by_index) == f"{suite.path}: cases[0].prompts[1]: case a, prompt '@3 follows @ego': @3 is not valid"
    by_agent = refused(suite, 0, "@3 is not among the agents the model drives", "prompt")
    assert str(by_agent).startswith(f"{suite.path}: cases[0].prompts[1]: case a, prompt '@3 follows @ego': @3 is not")
    assert str(refused(suite, 0, "no", "ego")) == f"{suite.path}: cases[0].ego: case a: no"


def test_run_suite_refuses_a_bad_case_before_anything_is_written(tmp_path):
    write_scene(tmp_path, "good", agents=[2])
    cases = [{"name": "a", "scenario": "good.json"}, {"name": "b", "scenario": "good.json", "prompts": ["@4 brakes"]}]
    options = RunOptions(out=tmp_path / "out", planner="suites.fakes:GoodPlanner", env=FAKE_ENV, video=False)
    with pytest.raises(InputError, match=r"cases\[1\]\.prompts\[0\]: case b, prompt '@4 brakes': unknown agent @4"):
        run_suite(load_suite(write_suite(tmp_path, cases)), options)
    assert not options.out.exists()


def test_a_case_refused_at_reset_is_bad_input_after_whole_reports(tmp_path):
    """What only the model can refuse is found at reset: the run is bad input, its files whole (written atomically)."""
    write_scene(tmp_path, "good")
    write_scene(tmp_path, "refused", refuse_at_reset="@4 is not among the agents the model drives")
    cases = [
        {"name": "a", "scenario": "good.json"},
        {"name": "b", "scenario": "refused.json", "prompts": ["@2 slows down", "@4 brakes"]},
    ]
    options = RunOptions(out=tmp_path / "out", planner="suites.fakes:GoodPlanner", env=FAKE_ENV, video=False)
    with pytest.raises(InputError) as raised:
        run_suite(load_suite(write_suite(tmp_path, cases)), options)
    assert str(raised.value) == (
        f"{tmp_path / 'suite.yaml'}: cases[1].prompts[1]: case b, prompt '@4 brakes': @4 is not among the agents the "
        "model drives"
    )
    saved = json.loads((options.out / "results.json").read_text())
    assert saved["complete"] and [e["status"] for e in saved["episodes"]] == ["pass", "error"]
    assert saved["episodes"][1]["reasons"][0].startswith("bad input before the episode started: prompt: @4 is not")
    assert sorted(p.name for p in options.out.iterdir()) == ["junit.xml", "report.md", "results.json"]


def test_a_pair_behaviour_the_scene_rules_out_is_warned_before_the_run(tmp_path, road):
    """@3 drives beside the ego, not ahead of it in its lane: braking hard in front of it is ruled out, and said with
    the map's reason before any episode; a cut-in from the next lane is allowed and not warned about."""
    cases = [
        {"name": "brake", "scenario": "road.pkl", "prompts": ["@3 brakes hard in front of @ego"]},
        {"name": "cut", "scenario": "road.pkl", "prompts": ["@3 cuts in front of @ego with a 5 m gap"]},
    ]
    warnings = check_cases(load_suite(write_suite(tmp_path, cases)))
    assert warnings == [
        "case brake, prompt '@3 brakes hard in front of @ego': @3 cannot brake hard in front of @1: @1 is not "
        "behind it in its lane"
    ], warnings


def test_a_red_light_run_in_a_scene_without_signals_is_warned_as_undecided(tmp_path, road):
    cases = [{"name": "red", "scenario": "road.pkl", "prompts": ["@3 runs the red light across the path of @ego"]}]
    (warning,) = check_cases(load_suite(write_suite(tmp_path, cases)))
    assert warning.endswith(
        "@3 cannot run the red light across the path of @1: the scene has no traffic lights (the scene cannot tell)"
    ), warning
