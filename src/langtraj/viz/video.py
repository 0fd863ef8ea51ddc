"""Writers: a PNG of one step, an MP4 (H.264) or GIF of a step range; every file written atomically."""

from __future__ import annotations

import sys
from collections.abc import Iterable, Iterator
from pathlib import Path

import imageio.v3 as iio
import imageio_ffmpeg
import numpy as np
from PIL import Image
from tqdm import tqdm

from langtraj.errors import InputError
from langtraj.fileio import atomic_path
from langtraj.scenario.model import Scenario
from langtraj.viz.config import RenderConfig
from langtraj.viz.topdown import TopDownRenderer, render_frame

VIDEO_SUFFIXES = (".mp4", ".gif")

MP4_BLOCK = 2
"""H.264 with 4:2:0 chroma needs even frame sides; frames are edge-padded up to a multiple of this."""


def save_png(scenario: Scenario, step: int, path: str | Path, config: RenderConfig | None = None) -> None:
    """Write step `step` of `scenario` as a PNG at `path`."""
    image = render_frame(scenario, step, config)
    with atomic_path(path) as tmp:
        iio.imwrite(tmp, image, extension=".png")


def pad_to_block(frame: np.ndarray, block: int = MP4_BLOCK) -> np.ndarray:
    """Edge-pad a frame [H, W, 3] on the bottom and right so both sides are multiples of `block`."""
    h, w = frame.shape[:2]
    pad_h, pad_w = -h % block, -w % block
    if pad_h or pad_w:
        frame = np.pad(frame, ((0, pad_h), (0, pad_w), (0, 0)), mode="edge")
    return np.ascontiguousarray(frame)


def write_mp4(path: Path, frames: Iterable[np.ndarray], fps: float) -> int:
    """Encode RGB frames as H.264 (yuv420p) MP4 through ffmpeg; returns the number written."""
    writer = None
    count = 0
    try:
        for frame in frames:
            frame = pad_to_block(frame)
            if writer is None:
                h, w = frame.shape[:2]
                writer = imageio_ffmpeg.write_frames(
                    str(path), (w, h), fps=float(fps), codec="libx264", pix_fmt_in="rgb24",
                    pix_fmt_out="yuv420p", quality=None, macro_block_size=1, ffmpeg_log_level="error",
                    output_params=["-preset", "veryfast", "-crf", "20", "-movflags", "+faststart"],
                )  # fmt: skip
                writer.send(None)
            writer.send(frame)
            count += 1
    finally:
        if writer is not None:
            writer.close()  # waits for ffmpeg to finish the file
    if count and path.stat().st_size == 0:
        raise OSError(f"ffmpeg wrote no video to {path}")
    return count


def write_gif(path: Path, frames: Iterable[np.ndarray], fps: float) -> int:
    """Write RGB frames as a looping GIF (each frame quantised to its own 256-colour palette)."""
    images = [Image.fromarray(f).quantize(colors=256, method=Image.Quantize.FASTOCTREE) for f in frames]
    if images:
        images[0].save(
            path, format="GIF", save_all=True, append_images=images[1:],
            duration=round(1000.0 / fps), loop=0, disposal=1,
        )  # fmt: skip
    return len(images)


def save_video(
    scenario: Scenario,
    path: str | Path,
    config: RenderConfig | None = None,
    start: int = 0,
    stop: int | None = None,
    progress: bool = True,
) -> int:
    """Render steps [start, stop) of `scenario` to `path` (.mp4 or .gif, by suffix); returns the
    number of frames. Shows a progress bar on stderr when `progress`. The file appears only when
    complete."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in VIDEO_SUFFIXES:
        raise InputError(f"unknown video suffix {path.suffix!r}; use .mp4 or .gif", path=path)
    stop = scenario.num_steps if stop is None else int(stop)
    if not 0 <= start < stop <= scenario.num_steps:
        raise InputError(
            f"step range [{start}, {stop}) is empty or outside [0, {scenario.num_steps})",
            where=scenario.scenario_id,
        )
    config = config if config is not None else RenderConfig()
    steps = range(start, stop)
    with TopDownRenderer(scenario, config, steps=steps) as renderer:
        bar = tqdm(steps, desc=f"render {path.name}", unit="frame", file=sys.stderr, disable=not progress)

        def frames() -> Iterator[np.ndarray]:
            for step in bar:
                yield renderer.frame(step)

        with atomic_path(path) as tmp:
            try:
                write = write_mp4 if suffix == ".mp4" else write_gif
                return write(tmp, frames(), config.fps)
            finally:
                bar.close()
