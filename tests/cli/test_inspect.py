"""`langtraj inspect` on real and constructed files, the installed console script, and a reader that leaves
early."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

from cli.helpers import run_cli


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


def test_a_box_repaired_on_read_is_one_warning_line(real_data_dir: Path, capsys) -> None:
    """nuScenes' ego is wider than long in the files: read turned round, and said so in one line on stderr."""
    path = real_data_dir / "sd_nuscenes_v1.0-mini_scene-0061.pkl"
    code, out, err = run_cli(["inspect", path, "--json"], capsys)
    assert code == 0 and json.loads(out)[0]["scenario_id"] == "scene-0061"
    assert err.splitlines() == [
        f"langtraj inspect: warning: {path}: scenario scene-0061: vehicle @62 (1.73 m long, 4.08 m wide) wider than "
        "long: length and width swapped"
    ]
