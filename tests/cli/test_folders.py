"""Folders of scenario files for every verb that takes several (`inspect`, `convert`, `interdrive build`,
`evaluate`, `submit`): searched recursively, skipping what is not a scenario file."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from scenario_builders import make_scenario

from cli.helpers import METADATA, assert_one_line_error, run_cli
from langtraj.rollouts.baselines import generate_baseline
from langtraj.scenario.io import read_scenario, read_scenarios, write_scenarios


@pytest.fixture
def corpus_folder(tmp_path: Path) -> Path:
    """Scenario files in nested folders among files of other kinds, as `langtraj synth --out` leaves
    them: a hidden folder (an unfinished write), a manifest, a README and an empty file are skipped."""
    root = tmp_path / "corpus"
    scenes = [make_scenario(5, scenario_id=name, seed=n) for n, name in enumerate(("a", "b0", "b1", "hidden"))]
    write_scenarios(root / "shards" / "b.tfrecord", scenes[1:3])
    write_scenarios(root / "shards" / "a" / "deep" / "a.pkl", scenes[:1])
    write_scenarios(root / ".partial" / "c.tfrecord", scenes[3:])
    (root / "manifest.json").write_text("{}")
    (root / "README.md").write_text("scenario files are in shards/")
    (root / "shards" / "empty.tfrecord").write_bytes(b"")
    return root


FOLDER_ORDER = [("shards/a/deep/a.pkl", "a"), ("shards/b.tfrecord", "b0"), ("shards/b.tfrecord", "b1")]
"""What `corpus_folder` holds, in the order a folder is searched (sorted by relative path)."""


def test_inspect_searches_folders_recursively(corpus_folder: Path, toy_file: Path, capsys) -> None:
    code, out, _ = run_cli(["inspect", toy_file, corpus_folder, "--json"], capsys)
    assert code == 0
    found = [(Path(s["file"]), s["scenario_id"]) for s in json.loads(out)]
    assert found == [(toy_file, "toy"), (toy_file, "b")] + [(corpus_folder / f, i) for f, i in FOLDER_ORDER]
    code, out, _ = run_cli(["inspect", corpus_folder / "shards"], capsys)
    assert code == 0 and len(out.strip().splitlines()) == 3
    # a file named explicitly is read (and refused) as before, even where a folder search skips it
    assert_one_line_error(*run_cli(["inspect", corpus_folder / "README.md"], capsys)[::2], "not a scenario file")


def test_interdrive_build_and_convert_take_folders(corpus_folder: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "labels"
    code, stdout, _ = run_cli(["interdrive", "build", corpus_folder, "--out", out], capsys)
    assert code == 0 and stdout.startswith("3 windows")
    manifest = json.loads((out / "manifest.json").read_text())
    sources = [(corpus_folder / f).resolve() for f in ("shards/a/deep/a.pkl", "shards/b.tfrecord")]
    assert [Path(s["source"]) for s in manifest["shards"]] == sources
    merged = tmp_path / "merged.tfrecord"
    assert run_cli(["convert", corpus_folder, merged], capsys)[0] == 0
    assert [s.scenario_id for s in read_scenarios(merged)] == [i for _, i in FOLDER_ORDER]


def test_evaluate_and_submit_take_folders(corpus_folder: Path, tmp_path: Path, capsys) -> None:
    rollouts = tmp_path / "rollouts"
    for file, index in (("shards/a/deep/a.pkl", 0), ("shards/b.tfrecord", 1)):
        scene = read_scenario(corpus_folder / file, index)
        generate_baseline("constant_velocity", scene).save(rollouts / f"{scene.scenario_id}.npz")
    code, out, _ = run_cli(["evaluate", corpus_folder, rollouts, "--json"], capsys)
    assert code == 0
    report = json.loads(out)
    assert [s["scenario_id"] for s in report["scenarios"]] == ["a", "b1"]
    code, out, _ = run_cli(["evaluate", corpus_folder, rollouts / "b1.npz", "--json"], capsys)
    assert code == 0 and json.loads(out) == report["scenarios"][1]
    code, _, err = run_cli(["evaluate", corpus_folder, rollouts / "b1.npz", "--index", "1"], capsys)
    assert_one_line_error(code, err, "--index")
    meta = tmp_path / "meta.json"
    meta.write_text(json.dumps(METADATA))
    code, out, _ = run_cli(["submit", corpus_folder, rollouts, "--metadata", meta, "--out", tmp_path / "sub"], capsys)
    assert code == 0 and out.startswith("2 scenarios")


@pytest.mark.parametrize("verb", ["inspect", "convert", "interdrive build", "evaluate", "submit"])
def test_a_folder_without_scenario_files_is_one_line(tmp_path: Path, capsys, verb: str) -> None:
    empty = tmp_path / "empty"
    (empty / "sub" / ".hidden").mkdir(parents=True)
    (empty / "sub" / "notes.txt").write_text("no scenarios here")
    (empty / "sub" / "zero.tfrecord").write_bytes(b"")
    write_scenarios(empty / "sub" / ".hidden" / "s.tfrecord", [make_scenario()])
    rollouts = tmp_path / "rollouts"
    generate_baseline("constant_velocity", make_scenario()).save(rollouts / "toy.npz")
    meta = tmp_path / "meta.json"
    meta.write_text(json.dumps(METADATA))
    out = tmp_path / "out"
    args = {
        "inspect": ["inspect", empty],
        "convert": ["convert", empty, out / "all.tfrecord"],
        "interdrive build": ["interdrive", "build", empty, "--out", out],
        "evaluate": ["evaluate", empty, rollouts, "--out", out / "report.json"],
        "submit": ["submit", empty, rollouts, "--metadata", meta, "--out", out],
    }[verb]
    code, stdout, err = run_cli(args, capsys)
    assert_one_line_error(code, err, f"{empty}: no scenario file in this folder or its subfolders")
    assert stdout == "" and not out.exists()
