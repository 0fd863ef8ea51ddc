"""`langtraj test`: exit codes, outputs and flags, through a fake env; and one run through the real env on real
scenes."""

from __future__ import annotations

import json
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
import yaml
from suites.fakes import FAKE_ENV, TESTS_DIR, write_scene

from cli.helpers import assert_one_line_error, run_cli


@pytest.fixture
def fake_env(monkeypatch):
    monkeypatch.setattr("langtraj.suites.episode.DEFAULT_ENV", FAKE_ENV)


@pytest.fixture
def suite_file(tmp_path: Path) -> Path:
    write_scene(tmp_path, "good")
    write_scene(tmp_path, "bad")
    path = tmp_path / "suite.yaml"
    cases = [{"name": "good-case", "scenario": "good.json"}, {"name": "bad-case", "scenario": "bad.json"}]
    path.write_text(yaml.safe_dump({"name": "cli", "cases": cases}))
    return path


def test_every_case_passes_exit_0(tmp_path, suite_file, fake_env, capsys):
    out = tmp_path / "out"
    code, stdout, _ = run_cli(["test", suite_file, "--planner", "suites.fakes:GoodPlanner", "--out", out], capsys)
    assert code == 0
    assert "PASS  good-case seed 0" in stdout and "PASS: 0 of 2 cases failed" in stdout
    assert {p.name for p in out.iterdir()} == {"results.json", "report.md", "junit.xml"}


def test_a_failing_case_exits_1_with_its_video(tmp_path, suite_file, fake_env, capsys):
    out = tmp_path / "out"
    code, stdout, _ = run_cli(
        ["test", suite_file, "--planner", "suites.fakes:NaNPlanner", "--seeds", "2", "--out", out], capsys
    )
    assert code == 1
    assert "FAIL  bad-case seed 1 " in stdout and "planner returned a non-finite action at step 12" in stdout
    saved = json.loads((out / "results.json").read_text())
    assert len(saved["episodes"]) == 4 and saved["summary"]["cases_failed"] == 1
    assert sorted(p.name for p in (out / "videos").iterdir()) == ["bad-case-seed0.mp4", "bad-case-seed1.mp4"]
    tests = ET.parse(out / "junit.xml").getroot().find("testsuite")
    for seed in (0, 1):
        failure = tests.find(f"testcase[@name='bad-case[seed{seed}]']/failure")
        assert failure.get("message") == "planner returned a non-finite action at step 12"


def test_a_hanging_planner_command_exits_1(tmp_path, suite_file, fake_env, capsys, monkeypatch):
    monkeypatch.setenv("PYTHONPATH", str(TESTS_DIR))
    out = tmp_path / "out"
    command = f"{sys.executable} -m langtraj.planners.serve suites.fakes:HangingPlanner"
    code, stdout, _ = run_cli(
        ["test", suite_file, "--planner-cmd", command, "--step-timeout", "1", "--no-video", "--out", out], capsys
    )
    assert code == 1
    assert "PASS  good-case seed 0" in stdout and "planner timed out after 1 s at step 2" in stdout
    assert not (out / "videos").exists()


@pytest.mark.parametrize(
    ("args", "needles"),
    [
        (["--planner", "no_such_planner"], ["langtraj test: error:", "unknown planner 'no_such_planner'"]),
        (["--planner", "idm", "--seeds", "0"], ["--seeds: must be >= 1"]),
        (["--planner", "idm", "--workers", "0"], ["--workers: must be >= 1"]),
        (["--planner-cmd", "no-such-program-x"], ["--planner-cmd: no program"]),
    ],
)
def test_bad_flags_exit_2_before_anything_is_written(tmp_path, suite_file, fake_env, capsys, args, needles):
    out = tmp_path / "out"
    code, _, err = run_cli(["test", suite_file, *args, "--out", out], capsys)
    assert_one_line_error(code, err, *needles)
    assert not out.exists()


def test_a_bad_suite_exits_2(tmp_path, capsys):
    path = tmp_path / "suite.yaml"
    path.write_text("name: s\ncases:\n  - {name: a, scenario: missing.pkl}\n")
    out = tmp_path / "out"
    code, _, err = run_cli(["test", path, "--planner", "idm", "--out", out], capsys)
    assert_one_line_error(code, err, str(path), "cases[0].scenario: no such file")
    assert not out.exists()


def test_a_mistyped_sweep_parameter_exits_2(tmp_path, capsys):
    write_scene(tmp_path, "good")
    cases = [{"name": "c", "scenario": "good.json", "prompts": ["@5 keeps a ${gapp} m gap"], "sweep": {"gap": [5]}}]
    path = tmp_path / "suite.yaml"
    path.write_text(yaml.safe_dump({"name": "s", "cases": cases}))
    out = tmp_path / "out"
    code, _, err = run_cli(["test", path, "--planner", "idm", "--out", out], capsys)
    message = "${gapp} is not a sweep parameter of this case (its parameters: gap) nor an environment variable"
    assert_one_line_error(code, err, f"{path}: cases[0].prompts[0]: {message}; did you mean ${{gap}}?")
    assert not out.exists()


def test_a_prompt_the_scene_refuses_exits_2_before_any_episode(tmp_path, fake_env, capsys):
    write_scene(tmp_path, "good", agents=[5])
    cases = [
        {"name": "fine", "scenario": "good.json", "prompts": ["@5 slows down"]},
        {"name": "typo", "scenario": "good.json", "prompts": ["@5 slows down", "@55 brakes"]},
    ]
    path = tmp_path / "suite.yaml"
    path.write_text(yaml.safe_dump({"name": "s", "cases": cases}))
    out = tmp_path / "out"
    code, stdout, err = run_cli(["test", path, "--planner", "suites.fakes:GoodPlanner", "--out", out], capsys)
    assert_one_line_error(code, err, f"{path}: cases[1].prompts[1]: case typo, prompt '@55 brakes': unknown agent @55")
    assert stdout == "" and not out.exists()


def test_a_prompt_refused_at_reset_exits_2_leaving_whole_reports(tmp_path, fake_env, capsys):
    write_scene(tmp_path, "good")
    write_scene(tmp_path, "refused", refuse_at_reset="@6 is not among the agents the model drives")
    cases = [
        {"name": "fine", "scenario": "good.json"},
        {"name": "b", "scenario": "refused.json", "prompts": ["@6 brakes"]},
    ]
    path = tmp_path / "suite.yaml"
    path.write_text(yaml.safe_dump({"name": "s", "cases": cases}))
    out = tmp_path / "out"
    code, _, err = run_cli(["test", path, "--planner", "suites.fakes:GoodPlanner", "--out", out], capsys)
    assert_one_line_error(code, err, f"{path}: cases[1].prompts[0]: case b, prompt '@6 brakes': @6 is not among")
    assert json.loads((out / "results.json").read_text())["complete"]
    assert not [p for p in out.rglob("*") if p.name.startswith(".")]  # no temporary file left


def test_planner_flags_are_exclusive_and_one_is_required(tmp_path, suite_file, capsys):
    for args in (["--planner", "idm", "--planner-cmd", "x"], []):
        with pytest.raises(SystemExit) as raised:
            run_cli(["test", suite_file, *args, "--out", tmp_path / "out"], capsys)
        assert raised.value.code == 2


@pytest.mark.real_data
def test_a_suite_through_the_real_env(real_data_dir, tmp_path, capsys, monkeypatch):
    """Two short cases on real scenes with the constant-velocity planner: one passes, one fails an impossible
    TTC criterion (TTC is at most 5 s), so its video comes from the real env's `played()`."""
    monkeypatch.setenv("LANGTRAJ_REAL_DATA", str(real_data_dir))
    path = tmp_path / "suite.yaml"
    scene = "sd_training.tfrecord-00000-of-01000_8a346109094cd5aa.pkl"
    cases = [
        {"name": "womd", "scenario": "${LANGTRAJ_REAL_DATA}/motion_data_one_scenario.tfrecord"},
        {
            "name": "braking-lead",
            "scenario": "${LANGTRAJ_REAL_DATA}/" + scene,
            "ego": 1101,
            "prompts": ["@738 slows down"],
            "criteria": {"min_ttc": 5.5},
        },
    ]
    path.write_text(yaml.safe_dump({"name": "real", "defaults": {"max_steps": 5}, "cases": cases}))
    out = tmp_path / "out"
    code, stdout, _ = run_cli(["test", path, "--planner", "constant_velocity", "--out", out], capsys)
    assert code == 1, stdout
    saved = json.loads((out / "results.json").read_text())
    womd, lead = saved["episodes"]
    assert womd["status"] == "pass" and womd["figures"]["steps"] == 5, womd["reasons"]
    assert lead["status"] == "fail" and lead["ego"] == 1101 and lead["reasons"][0].startswith("min TTC 5.00 s < 5.5 s")
    assert lead["video"] == "videos/braking-lead-seed0.mp4" and (out / lead["video"]).stat().st_size > 0
    assert "## braking-lead: FAIL" in (out / "report.md").read_text()


@pytest.mark.real_data
def test_a_prompt_naming_an_agent_not_in_the_real_scene_exits_2_before_any_episode(real_data_dir, tmp_path, capsys):
    scene = str(real_data_dir / "sd_training.tfrecord-00000-of-01000_8a346109094cd5aa.pkl")
    cases = [
        {"name": "lead", "scenario": scene, "ego": 1101, "prompts": ["@738 slows down"]},
        {"name": "typo", "scenario": scene, "ego": 1101, "prompts": ["@7380 slows down"]},
    ]
    path = tmp_path / "suite.yaml"
    path.write_text(yaml.safe_dump({"name": "real", "cases": cases}))
    out = tmp_path / "out"
    code, _, err = run_cli(["test", path, "--planner", "constant_velocity", "--out", out], capsys)
    assert_one_line_error(code, err, f"{path}: cases[1].prompts[0]: case typo, prompt '@7380 slows down': unknown")
    assert not out.exists()
