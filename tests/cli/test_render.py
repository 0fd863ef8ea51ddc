"""`langtraj render`: PNG and video of a window, every real file, and bad options or output paths."""

from __future__ import annotations

from pathlib import Path

import pytest
from scenario_builders import make_scenario

from cli.helpers import assert_one_line_error, run_cli
from langtraj.scenario.io import read_scenario, write_scenarios


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


# Slow (1 min, every real file); `pytest -m slow`. tests/viz/test_video.py renders one real scene by default.
@pytest.mark.slow
def test_every_real_file_renders_to_mp4(real_files: list[Path], tmp_path: Path, capsys) -> None:
    import imageio_ffmpeg

    for path in real_files:
        out = tmp_path / f"{path.stem}.mp4"
        code, _, err = run_cli(["render", path, "--out", out, "--size", "240", "--no-progress"], capsys)
        assert code == 0, err
        frames, _ = imageio_ffmpeg.count_frames_and_secs(str(out))
        assert frames == read_scenario(path).num_steps


def test_unknown_index_window_and_follow_are_clear_errors(toy_file: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "x.png"
    assert_one_line_error(*run_cli(["render", toy_file, "--out", out, "--index", "5"], capsys)[::2], "index 5")
    assert_one_line_error(
        *run_cli(["render", toy_file, "--out", out, "--window", "3"], capsys)[::2], "--window: window 3 does not exist"
    )
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
