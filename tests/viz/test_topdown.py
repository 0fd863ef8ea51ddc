"""Top-down frames (`viz.topdown`, `viz.camera`): content, captions, agent colours, camera modes, and bad
steps, track ids and settings."""

from __future__ import annotations

import numpy as np
import pytest

from langtraj.errors import InputError
from langtraj.scenario.types import AgentType
from langtraj.viz import RenderConfig, TopDownRenderer, render_frame, save_video, style
from langtraj.viz.topdown import wrap_caption
from viz.helpers import NUM_STEPS, SDC_ID, SMALL, make_scenario, near_colour, pixel


def test_frame_shape_dtype_and_content():
    config = RenderConfig(size_px=160, show_ids=True, highlight_ids=(101,), show_legend=True, caption="hello")
    image = render_frame(make_scenario(), 6, config)
    assert image.shape == (160, 160, 3)
    assert image.dtype == np.uint8
    assert len(np.unique(image.reshape(-1, 3), axis=0)) > 50
    assert image.std() > 15


LONG_CAPTION = (
    "@7 slows down and yields to @4, who turns left across its path at the signalized intersection "
    "+ @4 collides with @7 while the light is green"
)


def test_wrap_caption_breaks_long_lines_at_spaces() -> None:
    wrapped = wrap_caption(LONG_CAPTION + "\nstep 3/11", 40)
    lines = wrapped.split("\n")
    assert len(lines) == 5 and lines[-1] == "step 3/11"
    assert all(len(line) <= 40 for line in lines)
    assert " ".join(lines[:-1]) == LONG_CAPTION
    assert wrap_caption("short\nlines", 40) == "short\nlines"
    assert wrap_caption("x" * 25, 10).split("\n") == ["x" * 10, "x" * 10, "x" * 5]  # one long word is broken


@pytest.mark.parametrize("size_px", [160, 480, 800])
def test_a_long_caption_is_wrapped_inside_the_image(size_px: int) -> None:
    """The demo's prompt captions are longer than a panel is wide: they wrap instead of being cut off."""
    with TopDownRenderer(make_scenario(), RenderConfig(size_px=size_px, caption=LONG_CAPTION)) as renderer:
        renderer.frame(3)
        caption = renderer._caption
        lines = caption.get_text().split("\n")
        assert len(lines) >= 3 and lines[-1].startswith("step  3/11")
        assert " ".join(lines[:-1]) == LONG_CAPTION
        box = caption.get_bbox_patch().get_window_extent(renderer._canvas.get_renderer())
        assert 0 < box.x0 < box.x1 < size_px and 0 < box.y0 < box.y1 <= size_px


def test_agent_colours_appear_at_their_positions():
    scenario = make_scenario()
    step = 6
    with TopDownRenderer(scenario, SMALL, steps=[step]) as renderer:
        image = renderer.frame(step)
        sdc_x, sdc_y = scenario.agents.xy[0, step]
        rear = pixel(renderer, step, (sdc_x - 1.5, sdc_y + 0.6))  # rear half, beside the heading tick
        assert near_colour(image, *rear, style.SDC_COLOR)
        ped = pixel(renderer, step, tuple(scenario.agents.xy[3, step]))
        assert near_colour(image, *ped, style.AGENT_COLORS[AgentType.PEDESTRIAN])
        light = pixel(renderer, step, (3.0, 0.0))
        assert near_colour(image, *light, style.LIGHT_RED)


def test_invalid_agents_are_not_drawn():
    scenario = make_scenario()
    other = style.AGENT_COLORS[AgentType.OTHER]
    steps = [2, NUM_STEPS - 1]  # invalid at 2, valid at the end
    with TopDownRenderer(scenario, SMALL, steps=steps) as renderer:
        for step, expected in zip(steps, (False, True), strict=True):
            pos = pixel(renderer, step, tuple(scenario.agents.xy[5, step]))
            assert near_colour(renderer.frame(step), *pos, other, radius=1) is expected


def test_follow_mode_moves_the_view():
    scenario = make_scenario()
    config = RenderConfig(size_px=160, follow_track_id=SDC_ID, view_extent_m=30.0)
    with TopDownRenderer(scenario, config) as renderer:
        first, last = renderer.camera.limits(0), renderer.camera.limits(NUM_STEPS - 1)
        assert last[0] - first[0] == pytest.approx(8.0 * (NUM_STEPS - 1) * 0.1, abs=1e-3)
        assert first[1] - first[0] == pytest.approx(30.0)
        a, b = renderer.frame(0), renderer.frame(NUM_STEPS - 1)
        assert not np.array_equal(a, b)
        for image in (a, b):  # the followed car stays at the centre (rear half, off the tick)
            assert near_colour(image, 80, 80 - 10, style.SDC_COLOR, radius=3)


def test_scene_framing_is_fixed_and_covers_all_agents():
    scenario = make_scenario()
    with TopDownRenderer(scenario, SMALL) as renderer:
        limits = renderer.camera.limits(0)
        assert renderer.camera.limits(NUM_STEPS - 1) == limits
        xy = scenario.agents.xy[scenario.agents.valid]
        assert limits[0] < xy[:, 0].min() and xy[:, 0].max() < limits[1]
        assert limits[2] < xy[:, 1].min() and xy[:, 1].max() < limits[3]


def test_unknown_track_ids_are_input_errors(tmp_path):
    scenario = make_scenario()
    with pytest.raises(InputError, match="track id 999 is not in the scene"):
        render_frame(scenario, 0, RenderConfig(size_px=64, follow_track_id=999))
    with pytest.raises(InputError, match="track id 998 is not in the scene"):
        save_video(scenario, tmp_path / "a.mp4", RenderConfig(size_px=64, highlight_ids=(998,)), progress=False)
    assert list(tmp_path.iterdir()) == []


def test_bad_step_and_config_are_input_errors(tmp_path):
    scenario = make_scenario()
    with pytest.raises(InputError, match="step 99"):
        render_frame(scenario, 99, SMALL)
    with pytest.raises(InputError, match=r"step range \[5, 5\)"):
        save_video(scenario, tmp_path / "a.gif", SMALL, start=5, stop=5, progress=False)
    with pytest.raises(InputError, match="size_px"):
        RenderConfig(size_px=4)
