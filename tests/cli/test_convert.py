"""`langtraj convert`: real files both ways, many files to one and one file per scenario."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scenario_builders import make_scenario

from cli.helpers import assert_one_line_error, run_cli
from langtraj.scenario.compare import scenario_differences
from langtraj.scenario.io import read_scenario, read_scenarios


def test_convert_real_files_both_ways_keeps_what_both_formats_hold(real_files: list[Path], tmp_path: Path, capsys):
    for path in real_files:
        original = read_scenario(path)
        if path.suffix == ".pkl":
            there, back = tmp_path / f"{path.stem}.tfrecord", tmp_path / f"{path.stem}.back.pkl"
        else:
            there, back = tmp_path / f"{path.stem}.pkl", tmp_path / f"{path.stem}.back.tfrecord"
        assert run_cli(["convert", path, there], capsys)[0] == 0
        assert run_cli(["convert", there, back], capsys)[0] == 0
        converted, round_trip = read_scenario(there), read_scenario(back)
        for other in (converted, round_trip):
            diffs = scenario_differences(
                original, other, compare_invalid_states=False, compare_metadata=False, compare_polygons=False
            )
            assert diffs == [], f"{path.name}: {diffs[:3]}"
        if path.suffix == ".pkl":  # keys, types and source metadata come back through LangTraj's WOMD
            diffs = scenario_differences(original, round_trip, compare_invalid_states=False, compare_polygons=False)
            assert diffs == [], f"{path.name}: {diffs[:3]}"


def test_convert_many_to_one_and_one_per_file(toy_file: Path, tmp_path: Path, capsys) -> None:
    merged = tmp_path / "merged.tfrecord"
    assert run_cli(["convert", toy_file, toy_file, merged], capsys)[0] == 0
    assert [s.scenario_id for s in read_scenarios(merged)] == ["toy", "b", "toy", "b"]
    out_dir = tmp_path / "pkls"
    code, out, _ = run_cli(["convert", toy_file, out_dir, "--format", "scenarionet"], capsys)
    assert code == 0 and "wrote 2" in out
    assert sorted(p.name for p in out_dir.iterdir()) == ["b.pkl", "toy.pkl"]
    back = read_scenario(out_dir / "toy.pkl")
    np.testing.assert_array_equal(back.agents.states, make_scenario().agents.states)
    code, _, err = run_cli(["convert", toy_file, tmp_path / "two.pkl"], capsys)
    assert_one_line_error(code, err, "one scenario")
    assert not (tmp_path / "two.pkl").exists()
