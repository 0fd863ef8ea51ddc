"""`langtraj suggest`: the stagings of scene files as a table, as JSON and as a suite that `load_suite` reads, one
case per staging; bad input is one line and exit status 2 with no suite left behind; and on the shared real scenes,
a list for each scene and a suite that loads."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from scenario_builders import make_scenario, two_lane_road

from langtraj.interdrive.behaviours import kind
from langtraj.scenario.io import write_scenarios
from langtraj.suites.config import load_suite

from .helpers import assert_one_line_error, run_cli

STARTS = [(0.0, 0.0, 10.0), (0.0, 3.5, 10.0), (25.0, 0.0, 10.0), (-15.0, 0.0, 10.0)]
"""The ego in the right lane, a car level with it on its left, its lead and a follower (`two_lane_road`)."""


@pytest.fixture
def road_file(tmp_path: Path) -> Path:
    path = tmp_path / "scenes" / "road.tfrecord"
    path.parent.mkdir()
    write_scenarios(path, [two_lane_road(STARTS), two_lane_road(STARTS[:2], scenario_id="pair")])
    return path


def test_the_table_lists_each_scene_with_its_stagings_and_their_prompts(road_file, capsys):
    code, out, err = run_cli(["suggest", road_file], capsys)
    assert code == 0, err
    assert f"{road_file} [0] straight: ego @1," in out and f"{road_file} [1] pair: ego @1," in out
    assert "@2 cuts in front of @ego with a 10 m gap" in out and "@1's lane on its right, 10 m ahead of it" in out
    assert "@3 brakes hard at 6 m/s^2 in front of @ego" in out and "@4 tailgates @ego" in out
    # in the first scene the ego's lead, 20.5 m ahead of it, leaves no room for a 15-m cut-in or overtake
    assert out.strip().splitlines()[-1].startswith("14 stagings in 2 scene(s) (follow 1, cut_in 5, overtake_cut_in 5,")


def test_json_and_the_suite_hold_one_case_per_staging_and_the_suite_loads(road_file, tmp_path, capsys):
    suite = tmp_path / "runs" / "suggested.yaml"
    code, out, err = run_cli(["suggest", road_file, "--index", "0", "--json", "--suite", suite], capsys)
    assert code == 0, err
    stagings = json.loads(out)  # nothing else on standard output
    assert {s["index"] for s in stagings} == {0} and f"wrote {suite}" in err
    first = stagings[0]
    assert set(first) >= {"scene", "window", "agent", "other", "behaviour", "parameters", "prompt", "reason", "score"}
    assert [s["score"] for s in stagings] == sorted(s["score"] for s in stagings)
    loaded = load_suite(suite)
    assert loaded.name == "suggested" and len(loaded.cases) == len(stagings)
    for case, staging in zip(loaded.cases, stagings, strict=True):
        assert Path(case.scenario).resolve() == road_file.resolve() and case.index == 0 and case.window is None
        assert case.ego == 1 and case.prompts == (staging["prompt"],) and case.seeds == (0,)
        in_path = kind(staging["behaviour"]).in_path  # a cut-in, a braking lead: any collision fails; a tailgater not
        assert case.criteria.no_collision is in_path and case.criteria.no_at_fault_collision
    assert {kind(s["behaviour"]).in_path for s in stagings} == {True, False}
    assert "# @1's lane on its right, 10 m ahead of it, at 13.6 m/s (score 3.98)" in suite.read_text()
    names = [c.name for c in loaded.cases]
    assert "straight-2-cut-in-gap-10" in names and "straight-3-brake-hard-deceleration-6" in names


def test_only_the_asked_behaviour_another_ego_and_a_window(road_file, capsys):
    code, out, err = run_cli(
        ["suggest", road_file, "--index", "0", "--behaviour", "brake-hard", "--ego", "4", "--json"], capsys
    )
    assert code == 0, err
    stagings = json.loads(out)
    # @3, 36 m ahead of @4 at 10 m/s (3.6 s), would brake with its follower too far behind to test it (`ready`)
    assert {(s["agent"], s["behaviour"], s["other"]) for s in stagings} == {(1, "brake_hard", 4)}
    code, out, err = run_cli(["suggest", road_file, "--index", "1", "--window", "0", "--json"], capsys)
    assert code == 0, err
    assert {s["window"] for s in json.loads(out)} == {0}


@pytest.mark.parametrize(
    ("flags", "needles"),
    [
        (["--ego", "99"], ["road.tfrecord", "--ego", "no track 99 in scene straight"]),
        (["--behaviour", "cut_inn"], ["--behaviour", "did you mean 'cut_in'?"]),
        (["--behaviour", "turn_left"], ["--behaviour", "not a behaviour toward another agent"]),
        (["--window", "1"], ["road.tfrecord", "--window", "window 1 does not exist"]),
        (["--index", "-1"], ["--index", "must be >= 0"]),
    ],
)
def test_bad_flags_are_one_line_naming_the_flag_and_leave_no_suite(road_file, tmp_path, capsys, flags, needles):
    suite = tmp_path / "out.yaml"
    code, _, err = run_cli(["suggest", road_file, "--suite", suite, *flags], capsys)
    assert_one_line_error(code, err, *needles)
    assert not suite.exists() and not list(tmp_path.glob(".out.yaml*"))


def test_a_missing_file_and_nothing_to_stage_are_one_line(tmp_path, capsys):
    code, _, err = run_cli(["suggest", tmp_path / "nowhere.tfrecord"], capsys)
    assert_one_line_error(code, err, "nowhere.tfrecord")
    alone = tmp_path / "alone.tfrecord"
    write_scenarios(alone, [make_scenario(num_agents=1)])
    code, out, err = run_cli(["suggest", alone], capsys)
    assert code == 0 and "0 stagings" in out and "(none the map allows" in out
    code, _, err = run_cli(["suggest", alone, "--suite", tmp_path / "s.yaml"], capsys)
    assert_one_line_error(code, err, "--suite", "no staging found")
    assert not (tmp_path / "s.yaml").exists()


@pytest.mark.filterwarnings("ignore::langtraj.errors.DataWarning")
def test_every_real_scene_gets_a_list_and_the_suite_loads(real_data_dir: Path, real_files, tmp_path, capsys):
    suite = tmp_path / "runs" / "suggested.yaml"
    code, out, err = run_cli(["suggest", real_data_dir, "--json", "--suite", suite], capsys)
    assert code == 0, err
    stagings = json.loads(out)
    assert {Path(s["scene"]).name for s in stagings} == {p.name for p in real_files}  # every scene stages something
    loaded = load_suite(suite)
    assert [c.prompts[0] for c in loaded.cases] == [s["prompt"] for s in stagings]
    assert {Path(c.scenario).resolve() for c in loaded.cases} == {p.resolve() for p in real_files}
