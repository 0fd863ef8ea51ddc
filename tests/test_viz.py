"""Top-down rendering: frames, PNG, MP4 and GIF output, camera modes and error handling."""

from __future__ import annotations

import json
import re
from dataclasses import replace
from pathlib import Path

import imageio.v3 as iio
import imageio_ffmpeg
import numpy as np
import pytest
from matplotlib.colors import to_rgb
from PIL import Image

from langtraj.errors import InputError
from langtraj.scenario.model import Agents, MapFeature, RoadMap, Scenario, TrafficLights
from langtraj.scenario.types import AgentType, MapFeatureType, TrafficLightState
from langtraj.viz import (
    RenderConfig,
    TargetMark,
    TopDownRenderer,
    marks_from_prompt,
    render_frame,
    save_png,
    save_video,
    style,
)
from langtraj.viz.topdown import wrap_caption

REAL_DIR = Path(__file__).resolve().parents[2] / "shared" / "data" / "real"
SMALL = RenderConfig(size_px=160, trail_steps=5)
NUM_STEPS = 12
SDC_ID = 100


def make_scenario(num_steps: int = NUM_STEPS) -> Scenario:
    """A small crossing: the SDC and two vehicles drive along x, a pedestrian, a cyclist and an
    'other' agent move across; one lane, road line, road edge, crosswalk, stop sign and signal."""
    t = np.arange(num_steps) * 0.1
    # (id, type, start xy, velocity xy, length, width)
    tracks = [
        (SDC_ID, AgentType.VEHICLE, (-20.0, 0.0), (8.0, 0.0), 5.0, 2.4),
        (101, AgentType.VEHICLE, (-5.0, 4.0), (6.0, 0.0), 4.5, 2.0),
        (102, AgentType.VEHICLE, (15.0, -4.0), (-5.0, 0.0), 4.5, 2.0),
        (200, AgentType.PEDESTRIAN, (8.0, -10.0), (0.0, 1.4), 0.6, 0.6),
        (300, AgentType.CYCLIST, (-10.0, 10.0), (0.0, -4.0), 1.8, 0.7),
        (400, AgentType.OTHER, (20.0, 10.0), (-1.0, -1.0), 1.0, 1.0),
    ]
    states = np.zeros((len(tracks), num_steps, 9), np.float32)
    for a, (_, _, (x, y), (vx, vy), length, width) in enumerate(tracks):
        states[a, :, 0] = x + vx * t
        states[a, :, 1] = y + vy * t
        states[a, :, 3] = np.arctan2(vy, vx)
        states[a, :, 4], states[a, :, 5] = vx, vy
        states[a, :, 6], states[a, :, 7], states[a, :, 8] = length, width, 1.5
    valid = np.ones((len(tracks), num_steps), bool)
    valid[5, : num_steps // 2] = False  # the 'other' agent appears halfway
    agents = Agents(ids=[tr[0] for tr in tracks], types=[int(tr[1]) for tr in tracks], states=states, valid=valid)
    xs = np.linspace(-40, 40, 17)
    features = [
        MapFeature(1, MapFeatureType.LANE_SURFACE_STREET, np.stack([xs, np.zeros_like(xs)], 1)),
        MapFeature(2, MapFeatureType.LANE_BIKE_LANE, np.stack([xs, np.full_like(xs, -7.0)], 1)),
        MapFeature(3, MapFeatureType.ROAD_LINE_BROKEN_SINGLE_WHITE, np.stack([xs, np.full_like(xs, 2.0)], 1)),
        MapFeature(4, MapFeatureType.ROAD_LINE_SOLID_DOUBLE_YELLOW, np.stack([xs, np.full_like(xs, -2.0)], 1)),
        MapFeature(5, MapFeatureType.ROAD_EDGE_BOUNDARY, np.stack([xs, np.full_like(xs, 6.0)], 1)),
        MapFeature(6, MapFeatureType.CROSSWALK, [(5, -6), (11, -6), (11, 6), (5, 6)]),
        MapFeature(7, MapFeatureType.SPEED_BUMP, [(-30, -1), (-29, -1), (-29, 1), (-30, 1)]),
        MapFeature(8, MapFeatureType.DRIVEWAY, [(-15, 6), (-10, 6), (-10, 12), (-15, 12)]),
        MapFeature(9, MapFeatureType.STOP_SIGN, [(4.0, 3.0, 0.0)], controlled_lanes=(1,)),
    ]
    lights = TrafficLights(
        lane_ids=[1],
        states=np.full((num_steps, 1), int(TrafficLightState.STOP)),
        valid=np.ones((num_steps, 1), bool),
        stop_points=[(3.0, 0.0, 0.0)],
    )
    return Scenario("test-scene", t, 3, 0, agents, RoadMap(features), lights)


def pixel(renderer: TopDownRenderer, step: int, xy: tuple[float, float]) -> tuple[int, int]:
    """(row, col) of a world point in the frame of `step`."""
    x0, x1, y0, y1 = renderer.camera.limits(step)
    size = renderer.config.size_px
    return int((y1 - xy[1]) / (y1 - y0) * size), int((xy[0] - x0) / (x1 - x0) * size)


def near_colour(image: np.ndarray, row: int, col: int, colour: str, radius: int = 2, tol: int = 30) -> bool:
    target = np.array(to_rgb(colour)) * 255
    patch = image[max(row - radius, 0) : row + radius + 1, max(col - radius, 0) : col + radius + 1]
    return bool((np.abs(patch.astype(float) - target).max(axis=-1) <= tol).any())


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


# ----------------------------------------------------------------------------- target marks
MARKS = (
    TargetMark(((-25.0, -15.0), (-5.0, -15.0), (15.0, -15.0)), "path"),
    TargetMark(((-2.0, -19.0), (2.0, -19.0)), "stop"),
    TargetMark(((12.0, 14.0),), "goal"),
    TargetMark(((-14.0, 14.0),), "conflict"),
)


def test_marks_are_drawn_at_their_points_and_nowhere_else():
    scenario = make_scenario()
    step = 6
    config = RenderConfig(size_px=400, trail_steps=0)
    with TopDownRenderer(scenario, config, steps=[step]) as plain:
        without = plain.frame(step)
    with TopDownRenderer(scenario, replace(config, marks=MARKS), steps=[step]) as marked:
        assert marked.camera.limits(step) == plain.camera.limits(step)  # marks do not move the view
        image = marked.frame(step)
        changed = np.abs(image.astype(int) - without.astype(int)).max(axis=-1) > 30
        near = np.zeros_like(changed)
        for mark in MARKS:
            rows, cols = zip(*(pixel(marked, step, tuple(p)) for p in mark.points), strict=True)
            near[max(min(rows) - 9, 0) : max(rows) + 10, max(min(cols) - 9, 0) : max(cols) + 10] = True
            assert changed[near].any()
        assert changed.any() and not changed[~near].any()
        for xy, colour in (
            ((-5.0, -15.0), style.MARK_COLOR),
            ((0.0, -19.0), style.MARK_STOP_COLOR),
            ((12.0, 14.0), style.MARK_GOAL_COLOR),
            ((-14.0, 14.0), style.MARK_CONFLICT_COLOR),
        ):
            row, col = pixel(marked, step, xy)
            assert near_colour(image, row, col, colour, radius=4, tol=40)  # the path is a little transparent
            assert not near_colour(without, row, col, colour, radius=4, tol=40)


def test_marks_stay_in_cached_frames_and_move_with_a_following_camera():
    scenario = make_scenario()
    goal = TargetMark(((-14.0, -6.0),), "goal", label="@100 stop")
    fixed = RenderConfig(size_px=320, marks=(goal,))
    with TopDownRenderer(scenario, fixed) as renderer:  # the map and marks are blitted from the cache
        for step in (0, 5, NUM_STEPS - 1):
            assert near_colour(renderer.frame(step), *pixel(renderer, step, (-14.0, -6.0)), style.MARK_GOAL_COLOR)
    follow = replace(fixed, follow_track_id=SDC_ID, view_extent_m=30.0)
    with TopDownRenderer(scenario, follow) as renderer:
        first, last = pixel(renderer, 0, (-14.0, -6.0)), pixel(renderer, NUM_STEPS - 1, (-14.0, -6.0))
        assert last[1] < first[1] - 60  # the camera moved right, so the goal moved left in the image
        assert near_colour(renderer.frame(0), *first, style.MARK_GOAL_COLOR)
        image = renderer.frame(NUM_STEPS - 1)
        assert near_colour(image, *last, style.MARK_GOAL_COLOR)
        assert not near_colour(image, *first, style.MARK_GOAL_COLOR)


def test_marks_from_prompt_reads_the_prompt_report():
    path = [[float(x), 0.0] for x in range(0, 40, 2)]
    report = {
        "read": [],
        "steering": [],
        "targets": [
            {"track_id": 7, "behaviour": "stop", "path": path, "goal": [19.0, 0.0], "stop": True, "conflict": None},
            {"track_id": 7, "behaviour": "turn_left", "path": path, "goal": [30.0, 0.0], "stop": False},
            {"track_id": 7, "behaviour": "yield", "path": path, "goal": [10.0, 0.0], "stop": False,
             "conflict": [10.0, 0.0], "other_id": 4, "first": False},
            {"track_id": 9, "behaviour": "speed_up", "path": [], "goal": None, "stop": False, "conflict": None},
        ],
    }  # fmt: skip
    marks = marks_from_prompt(json.loads(json.dumps(report)))
    assert [m.kind for m in marks] == ["path", "stop", "path", "goal", "path", "conflict"]
    assert marks[0].points == (*((x, y) for x, y in path[:10]), (19.0, 0.0))  # up to the stop, where it is to stay
    assert marks[2].points == tuple((x, y) for x, y in path)
    (x0, y0), (x1, y1) = marks[1].points  # a stop bar across the path at the goal
    assert x0 == x1 == 19.0 and abs(y1 - y0) == pytest.approx(style.MARK_STOP_BAR_M)
    assert marks[1].label == "@7 stop" and marks[3].label == "@7 turn left"
    assert marks[3].points == ((30.0, 0.0),)
    assert marks[5].points == ((10.0, 0.0),) and marks[5].label == "@7 after @4"  # the goal is the conflict
    assert marks_from_prompt(None) == marks_from_prompt({}) == marks_from_prompt({"targets": []}) == ()
    render_frame(make_scenario(), 3, RenderConfig(size_px=64, marks=marks))  # every kind draws


@pytest.mark.parametrize(
    ("make", "field"),
    [
        (lambda: TargetMark(((0.0, 0.0), (float("nan"), 1.0)), "path"), r"points\[1\] must be finite"),
        (lambda: TargetMark(((0.0, 0.0), (1.0,)), "path"), r"points\[1\] must be two numbers"),
        (lambda: TargetMark(((0.0, 0.0),), "circle"), r"kind must be one of path, stop, goal, conflict"),
        (lambda: TargetMark(((0.0, 0.0),), "path"), r"points of a path mark must be at least two"),
        (lambda: TargetMark(((0.0, 0.0),) * 3, "stop"), r"points of a stop mark"),
        (lambda: TargetMark(((0.0, 0.0),), "goal", label="x" * 99), r"label must be one line"),
        (lambda: RenderConfig(marks=("goal",)), r"marks\[0\] must be a TargetMark, got str"),
        (lambda: RenderConfig(marks=TargetMark(((0.0, 0.0),), "goal")), r"marks must be a tuple of TargetMark"),
        (lambda: marks_from_prompt({"targets": [{"path": [[0, 0], [float("inf"), 1]]}]}), r"targets\[0\].*path\[1\]"),
        (lambda: marks_from_prompt({"targets": [{"path": [], "goal": [1.0, "a"]}]}), r"targets\[0\].*goal must"),
        (lambda: marks_from_prompt({"targets": {"a": 1}}), r"targets must be a list"),
    ],
)
def test_bad_marks_are_input_errors_naming_the_field(make, field):
    with pytest.raises(InputError, match=field):
        make()
