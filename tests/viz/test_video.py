"""PNG, MP4 and GIF output (`viz.video`): readable files, frame counts, atomic writes, and a real scene."""

from __future__ import annotations

import re
from pathlib import Path

import imageio.v3 as iio
import imageio_ffmpeg
import pytest
from PIL import Image

from langtraj.errors import InputError
from langtraj.viz import RenderConfig, TopDownRenderer, save_png, save_video
from viz.helpers import SMALL, make_scenario

REAL_DIR = Path(__file__).resolve().parents[3] / "shared" / "data" / "real"


def test_save_png_is_readable(tmp_path):
    path = tmp_path / "out" / "frame.png"
    save_png(make_scenario(), 4, path, SMALL)
    image = iio.imread(path)
    assert image.shape[:2] == (160, 160)
    assert sorted(p.name for p in path.parent.iterdir()) == ["frame.png"]


def test_save_mp4_frame_count_and_even_size(tmp_path):
    path = tmp_path / "clip.mp4"
    config = RenderConfig(size_px=101, trail_steps=3)  # odd size: padded to even for yuv420p
    assert save_video(make_scenario(), path, config, start=2, stop=9, progress=False) == 7
    frames = imageio_ffmpeg.read_frames(str(path))
    meta = next(frames)
    assert tuple(meta["size"]) == (102, 102)
    assert sum(1 for _ in frames) == 7
    assert [p.name for p in tmp_path.iterdir()] == ["clip.mp4"]


def test_save_gif_frame_count(tmp_path):
    path = tmp_path / "clip.gif"
    assert save_video(make_scenario(), path, RenderConfig(size_px=80), start=0, stop=5, progress=False) == 5
    with Image.open(path) as gif:
        assert gif.n_frames == 5
        assert gif.size == (80, 80)


def test_unknown_suffix_is_an_input_error_and_writes_nothing(tmp_path):
    path = tmp_path / "clip.avi"
    with pytest.raises(InputError, match=re.escape(str(path))):
        save_video(make_scenario(), path, SMALL, progress=False)
    assert list(tmp_path.iterdir()) == []


def test_failed_render_leaves_old_file_untouched(tmp_path, monkeypatch):
    path = tmp_path / "clip.mp4"
    path.write_bytes(b"old")
    calls = {"n": 0}
    original = TopDownRenderer.frame

    def failing(self, step):
        calls["n"] += 1
        if calls["n"] == 3:
            raise RuntimeError("boom")
        return original(self, step)

    monkeypatch.setattr(TopDownRenderer, "frame", failing)
    with pytest.raises(RuntimeError, match="boom"):
        save_video(make_scenario(), path, RenderConfig(size_px=64), progress=False)
    assert path.read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["clip.mp4"]


@pytest.mark.real_data
def test_real_scene_renders_to_mp4(tmp_path):
    path = REAL_DIR / "motion_data_one_scenario.tfrecord"
    if not path.exists():
        pytest.skip(f"real data not found: {path}")
    try:
        from langtraj.scenario.io import read_scenario
    except ImportError as exc:
        pytest.skip(f"langtraj.scenario.io.read_scenario is not available: {exc}")
    scenario = read_scenario(path)
    out = tmp_path / "real.mp4"
    config = RenderConfig(size_px=192, follow_track_id=scenario.sdc_id)
    assert save_video(scenario, out, config, progress=False) == scenario.num_steps == 91
    assert imageio_ffmpeg.count_frames_and_secs(str(out))[0] == 91
