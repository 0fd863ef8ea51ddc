"""The `langtraj` command: inspect, render and convert on real and constructed files, folders of scenario
files for every verb that takes several, and bad input."""

from __future__ import annotations

import json
import pickle
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from metrics.test_submit_cli import METADATA
from scenario_builders import make_scenario

from langtraj.cli.main import main
from langtraj.rollouts.baselines import generate_baseline
from langtraj.scenario.compare import scenario_differences
from langtraj.scenario.io import read_scenario, read_scenarios, write_scenarios
from langtraj.scenario.io.tfrecord import write_records
from langtraj.scenario.io.womd import scenario_to_proto


def run_cli(args: list[str], capsys: pytest.CaptureFixture) -> tuple[int, str, str]:
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


def assert_one_line_error(code: int, err: str, *needles: str) -> None:
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert "Traceback" not in err
    for needle in needles:
        assert needle in lines[0], lines[0]


@pytest.fixture
def toy_file(tmp_path: Path) -> Path:
    path = tmp_path / "toy.tfrecord"
    write_scenarios(path, [make_scenario(), make_scenario(scenario_id="b")])
    return path


# ------------------------------------------------------------------------------ inspect


def test_inspect_json_on_real_waymo_file(real_data_dir: Path, capsys) -> None:
    code, out, _ = run_cli(["inspect", real_data_dir / "motion_data_one_scenario.tfrecord", "--json"], capsys)
    assert code == 0
    (summary,) = json.loads(out)
    assert summary["scenario_id"] == "637f20cafde22ff8"
    assert summary["num_agents"] == 83
    assert summary["num_map_features"] == 301
    assert summary["num_steps"] == 91
    assert summary["current_index"] == 10
    assert summary["sdc_id"] == 2406
    assert summary["tracks_to_predict"] == [2320, 1676, 1675]
    assert summary["objects_of_interest"] == []
    assert summary["agent_type_counts"] == {"vehicle": 70, "pedestrian": 10, "cyclist": 3, "other": 0}
    assert summary["source_format"] == "womd"


def test_inspect_every_real_file(real_files: list[Path], capsys) -> None:
    code, out, _ = run_cli(["inspect", *real_files, "--json"], capsys)
    assert code == 0
    summaries = json.loads(out)
    assert len(summaries) == len(real_files) == 8
    by_id = {s["scenario_id"]: s for s in summaries}
    assert by_id["2a1e44d405a6833f"]["num_agents"] == 211
    assert by_id["8a346109094cd5aa"]["num_agents"] == 115
    assert all(191 <= s["num_steps"] <= 201 for s in summaries if s["scenario_id"].startswith("scene-"))
    assert {s["source_format"] for s in summaries} == {"womd", "scenarionet"}


def test_inspect_text_lists_each_scenario(toy_file: Path, capsys) -> None:
    code, out, _ = run_cli(["inspect", toy_file], capsys)
    assert code == 0
    assert len(out.strip().splitlines()) == 2
    assert "toy (womd): 4 agents" in out


# ------------------------------------------------------------------------------ bad input


def _pickle_calling_os_system(marker: Path) -> bytes:
    class Exploit:
        def __reduce__(self):
            import os

            return (os.system, (f"touch {marker}",))

    return pickle.dumps(Exploit(), protocol=4)


@pytest.mark.parametrize("verb", ["inspect", "render", "convert"])
def test_bad_inputs_give_one_line_and_no_output(tmp_path: Path, toy_file: Path, capsys, verb: str) -> None:
    good = toy_file.read_bytes()
    flipped = bytearray(good)
    flipped[200] ^= 0xFF
    nan_msg = scenario_to_proto(make_scenario())
    nan_msg.tracks[2].states[50].center_x = float("nan")
    marker = tmp_path / "pwned"
    cases = {
        "missing.tfrecord": None,
        "truncated.tfrecord": good[: len(good) // 2],
        "crc.tfrecord": bytes(flipped),
        "image.png": b"\x89PNG\r\n\x1a\n" + bytes(100),
        "notes.txt": b"scenario_id,x,y\n1,2,3\n",
        "empty.tfrecord": b"",
        "evil.pkl": _pickle_calling_os_system(marker),
    }
    expected = {
        "missing.tfrecord": "no such file",
        "truncated.tfrecord": "truncated",
        "crc.tfrecord": "checksum mismatch",
        "image.png": "not a scenario file",
        "notes.txt": "not a scenario file",
        "empty.tfrecord": "file is empty",
        "evil.pkl": "os",
    }
    write_records(tmp_path / "nan.tfrecord", [nan_msg.SerializeToString()])
    cases["nan.tfrecord"] = (tmp_path / "nan.tfrecord").read_bytes()
    expected["nan.tfrecord"] = "track 27, step 50: non-finite x"
    for name, data in cases.items():
        path = tmp_path / name
        if data is not None:
            path.write_bytes(data)
        out_file = tmp_path / "out" / f"{name}.mp4"
        args = {
            "inspect": ["inspect", path],
            "render": ["render", path, "--out", out_file, "--no-progress"],
            "convert": ["convert", path, tmp_path / "out" / f"{name}.converted.tfrecord"],
        }[verb]
        code, _, err = run_cli(args, capsys)
        assert_one_line_error(code, err, name, expected[name])
    assert not marker.exists(), "the pickle ran code"
    assert not (tmp_path / "out").exists() or list((tmp_path / "out").iterdir()) == []


def test_unknown_index_window_and_follow_are_clear_errors(toy_file: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "x.png"
    assert_one_line_error(*run_cli(["render", toy_file, "--out", out, "--index", "5"], capsys)[::2], "index 5")
    assert_one_line_error(*run_cli(["render", toy_file, "--out", out, "--window", "3"], capsys)[::2], "--window 3")
    assert_one_line_error(*run_cli(["render", toy_file, "--out", out, "--follow", "999"], capsys)[::2], "999")
    assert_one_line_error(*run_cli(["render", toy_file, "--out", tmp_path / "x.avi"], capsys)[::2], "x.avi")
    assert_one_line_error(*run_cli(["render", toy_file, "--out", out, "--step", "91"], capsys)[::2], "step 91")
    assert not out.exists()


def test_unwritable_output_is_one_line(toy_file: Path, tmp_path: Path, capsys) -> None:
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    code, _, err = run_cli(["render", toy_file, "--out", blocker / "x.png"], capsys)
    assert code == 1
    assert len(err.strip().splitlines()) == 1 and "a_file" in err and "Traceback" not in err


def test_console_script_is_installed(toy_file: Path) -> None:
    exe = shutil.which("langtraj") or str(Path(sys.executable).parent / "langtraj")
    done = subprocess.run([exe, "inspect", str(toy_file), "--json"], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    assert [s["scenario_id"] for s in json.loads(done.stdout)] == ["toy", "b"]
    bad = subprocess.run([exe, "inspect", str(toy_file) + ".nope"], capture_output=True, text=True, check=False)
    assert bad.returncode == 2
    assert bad.stderr.count("\n") == 1 and "no such file" in bad.stderr


def test_a_reader_that_leaves_early_is_not_an_error(toy_file: Path) -> None:
    """`langtraj inspect FILE --json | head -1` under `set -o pipefail`: the closed pipe ends the command with 0
    and nothing on standard error (a broken pipe is an OSError, caught before the generic branch)."""
    command = [sys.executable, "-m", "langtraj.cli.main", "inspect", str(toy_file), "--json"]
    job = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    job.stdout.close()  # the reader is gone before the first write
    _, err = job.communicate(timeout=120)
    assert job.returncode == 0 and err == b""


# ------------------------------------------------------------------------------ render


def test_render_png_and_video_of_a_window(tmp_path: Path, capsys) -> None:
    long_file = tmp_path / "long.tfrecord"
    write_scenarios(long_file, [make_scenario(num_steps=200)])
    code, out, _ = run_cli(["render", long_file, "--out", tmp_path / "a.png", "--ids", "--highlight", "7"], capsys)
    assert code == 0 and (tmp_path / "a.png").stat().st_size > 1000
    code, out, _ = run_cli(
        ["render", long_file, "--out", tmp_path / "w.gif", "--window", "1", "--size", "160", "--no-progress"], capsys
    )
    assert code == 0
    assert "91 frames of toy_w91" in out


def test_every_real_file_renders_to_mp4(real_files: list[Path], tmp_path: Path, capsys) -> None:
    import imageio_ffmpeg

    for path in real_files:
        out = tmp_path / f"{path.stem}.mp4"
        code, _, err = run_cli(["render", path, "--out", out, "--size", "240", "--no-progress"], capsys)
        assert code == 0, err
        frames, _ = imageio_ffmpeg.count_frames_and_secs(str(out))
        assert frames == read_scenario(path).num_steps


# ------------------------------------------------------------------------------ convert


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


# ------------------------------------------------------------------------------ folders


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
