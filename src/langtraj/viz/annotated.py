"""A scene with a text panel beside it: labels and prompts of a window, for checking labels by eye."""

from __future__ import annotations

import textwrap
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import imageio.v3 as iio
import numpy as np
from PIL import Image, ImageDraw, ImageFont

from langtraj.fileio import atomic_path
from langtraj.scenario.model import Scenario
from langtraj.viz.config import RenderConfig
from langtraj.viz.topdown import render_frame

PANEL_PX = 560
LINE_PX = 17
WRAP_CHARS = 70


def render_annotated(scenario: Scenario, lines: Sequence[str], config: RenderConfig | None = None) -> np.ndarray:
    """The last step of the scene with every agent's path as a trail, and `lines` in a panel on the right."""
    config = config or RenderConfig()
    last = scenario.num_steps - 1
    frame = render_frame(scenario, last, replace(config, trail_steps=scenario.num_steps - scenario.current_index))
    panel = Image.new("RGB", (PANEL_PX, frame.shape[0]), "white")
    draw = ImageDraw.Draw(panel)
    font = ImageFont.load_default(size=13)
    y = 10
    for line in lines:
        indent = len(line) - len(line.lstrip())
        for i, part in enumerate(textwrap.wrap(line.strip(), WRAP_CHARS - indent) or [""]):
            if y > frame.shape[0] - LINE_PX:
                draw.text((10, y), "...", fill="black", font=font)
                return np.concatenate([frame, np.asarray(panel)], axis=1)
            draw.text((10 + 7 * (indent + (2 if i else 0)), y), part, fill="black", font=font)
            y += LINE_PX
    return np.concatenate([frame, np.asarray(panel)], axis=1)


def save_annotated_png(
    scenario: Scenario, lines: Sequence[str], path: str | Path, config: RenderConfig | None = None
) -> None:
    """Write `render_annotated` as a PNG, atomically."""
    image = render_annotated(scenario, lines, config)
    with atomic_path(path) as tmp:
        iio.imwrite(tmp, image, extension=".png")
