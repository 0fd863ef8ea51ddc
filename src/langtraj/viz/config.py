"""RenderConfig: what a top-down frame or video shows and how large it is."""

from __future__ import annotations

import math
from dataclasses import dataclass

from langtraj.errors import InputError
from langtraj.viz.marks import TargetMark


@dataclass(frozen=True)
class RenderConfig:
    """Options of the top-down renderer.

    size_px: width and height of the square image in pixels.
    dpi: points-to-pixels scale of lines, markers and text; None uses size_px / 8, so the drawing
        keeps its proportions at any image size (larger dpi: thicker lines, larger text).
    follow_track_id: centre the view on this track at every frame (view_extent_m wide);
        None frames all valid agent positions of the rendered steps plus margin_m, fixed over a video.
    view_extent_m: width and height of the view in follow mode, in metres.
    margin_m: space around the agents in scene-framing mode, in metres.
    trail_steps: how many past steps of each agent's path to draw as a fading trail (0: none).
    show_ids: write each agent's track id beside it.
    highlight_ids: track ids drawn with a thick outline (e.g. the agents a prompt names).
    caption: first line of the caption; None shows the scenario id. Step and time follow it.
    fps: frames per second of saved videos.
    show_legend: draw a small legend of agent colours.
    marks: targets drawn on the map under the agents (`viz.marks.TargetMark`: a prompted agent's path, stop,
        goal or conflict point, world frame), e.g. `marks_from_prompt(summary["prompt"])`.
    """

    size_px: int = 800
    dpi: float | None = None
    follow_track_id: int | None = None
    view_extent_m: float = 80.0
    margin_m: float = 10.0
    trail_steps: int = 10
    show_ids: bool = False
    highlight_ids: tuple[int, ...] = ()
    caption: str | None = None
    fps: float = 10.0
    show_legend: bool = False
    marks: tuple[TargetMark, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "highlight_ids", tuple(int(i) for i in self.highlight_ids))
        problems = []
        marks = self.marks if isinstance(self.marks, tuple | list) else None
        if marks is None:
            problems.append(f"marks must be a tuple of TargetMark, got {type(self.marks).__name__}")
            marks = ()
        problems += [
            f"marks[{i}] must be a TargetMark, got {type(m).__name__}"
            for i, m in enumerate(marks)
            if not isinstance(m, TargetMark)
        ]
        object.__setattr__(self, "marks", tuple(marks))
        if int(self.size_px) != self.size_px or self.size_px < 16:
            problems.append(f"size_px must be an integer >= 16, got {self.size_px!r}")
        if self.dpi is not None and not (math.isfinite(self.dpi) and self.dpi > 0):
            problems.append(f"dpi must be positive, got {self.dpi!r}")
        if not (math.isfinite(self.view_extent_m) and self.view_extent_m > 0):
            problems.append(f"view_extent_m must be positive, got {self.view_extent_m!r}")
        if not (math.isfinite(self.margin_m) and self.margin_m >= 0):
            problems.append(f"margin_m must be >= 0, got {self.margin_m!r}")
        if int(self.trail_steps) != self.trail_steps or self.trail_steps < 0:
            problems.append(f"trail_steps must be an integer >= 0, got {self.trail_steps!r}")
        if not (math.isfinite(self.fps) and self.fps > 0):
            problems.append(f"fps must be positive, got {self.fps!r}")
        if problems:
            raise InputError("; ".join(problems), where="render config")
        object.__setattr__(self, "size_px", int(self.size_px))
        object.__setattr__(self, "trail_steps", int(self.trail_steps))

    @property
    def effective_dpi(self) -> float:
        return self.size_px / 8.0 if self.dpi is None else float(self.dpi)
