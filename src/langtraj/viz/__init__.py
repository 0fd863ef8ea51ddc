"""Top-down rendering of scenarios: single frames, PNG images and MP4/GIF videos (matplotlib, Agg)."""

from __future__ import annotations

from langtraj.viz.config import RenderConfig
from langtraj.viz.marks import TargetMark, marks_from_prompt
from langtraj.viz.topdown import TopDownRenderer, render_frame
from langtraj.viz.video import save_png, save_video

__all__ = [
    "RenderConfig",
    "TargetMark",
    "TopDownRenderer",
    "marks_from_prompt",
    "render_frame",
    "save_png",
    "save_video",
]
