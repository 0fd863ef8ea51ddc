"""The labeling tool's media: cached window videos and agents' pixel positions that match the frames."""

from __future__ import annotations

import dataclasses
import json
import math
import threading
import time
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest
from matplotlib.colors import to_rgb
from scenario_builders import make_scenario

from langtraj.errors import InputError
from langtraj.labeling import media
from langtraj.labeling.media import MediaConfig, agent_positions, nearest_agent, window_video
from langtraj.scenario import Scenario
from langtraj.viz import RenderConfig, TopDownRenderer, style

SIZE = 192
STEPS = 20
PAIR = (7, 17)


def spread_scenario(scenario_id: str = "toy") -> Scenario:
    """make_scenario's four agents (ids 7, 17, 27, 37; SDC vehicle, pedestrian, cyclist, other: four
    distinct fill colours) moved apart over the plane in four headings, so both image axes are tested;
    agent 27 is invalid for its first third."""
    scenario = make_scenario(4, STEPS, scenario_id=scenario_id)
    states = scenario.agents.states.copy()
    t = scenario.timestamps - scenario.timestamps[0]
    starts = [(-20.0, -15.0), (15.0, -10.0), (-10.0, 15.0), (20.0, 12.0)]
    headings = np.deg2rad([0.0, 90.0, 200.0, 315.0])
    for a, ((x0, y0), h) in enumerate(zip(starts, headings, strict=True)):
        speed = 5.0
        states[a, :, 0] = x0 + speed * np.cos(h) * t
        states[a, :, 1] = y0 + speed * np.sin(h) * t
        states[a, :, 3] = h
        states[a, :, 4] = speed * np.cos(h)
        states[a, :, 5] = speed * np.sin(h)
    return dataclasses.replace(scenario, agents=dataclasses.replace(scenario.agents, states=states))


def face_colors(scenario: Scenario) -> np.ndarray:
    """Each agent's fill colour [A, 3] in 0..255, as the renderer paints it."""
    names = [style.agent_color(t) for t in scenario.agents.types]
    names[scenario.sdc_index] = style.SDC_COLOR
    return np.array([to_rgb(c) for c in names]) * 255.0


@pytest.fixture(scope="module")
def scenario() -> Scenario:
    return spread_scenario()


@pytest.fixture(scope="module")
def config() -> MediaConfig:
    return MediaConfig(size_px=SIZE, fps=10)


@pytest.fixture(scope="module")
def video(scenario: Scenario, config: MediaConfig, tmp_path_factory: pytest.TempPathFactory) -> Path:
    return window_video(scenario, PAIR, tmp_path_factory.mktemp("media"), config)


def test_window_video_is_an_mp4_of_every_step(scenario: Scenario, config: MediaConfig, video: Path) -> None:
    assert video.is_file() and video.suffix == ".mp4"
    assert video.read_bytes()[4:8] == b"ftyp"
    frames = iio.imread(video, index=None)
    assert frames.shape == (scenario.num_steps, SIZE, SIZE, 3)
    assert [p.name for p in video.parent.iterdir()] == [video.name]  # no temporary file left behind


def test_window_video_is_cached(
    scenario: Scenario, config: MediaConfig, video: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    mtime = video.stat().st_mtime_ns

    def no_render(*args: object, **kwargs: object) -> int:
        raise AssertionError("rendered a cached video again")

    monkeypatch.setattr(media, "save_video", no_render)
    assert window_video(scenario, PAIR, video.parent, config) == video
    assert window_video(scenario, list(PAIR), video.parent, config) == video  # any sequence of ints
    assert video.stat().st_mtime_ns == mtime


def test_cache_key_follows_pair_config_and_content(scenario: Scenario, config: MediaConfig, video: Path) -> None:
    def path(s: Scenario = scenario, pair: tuple[int, ...] = PAIR, c: MediaConfig = config) -> Path:
        return media.video_path(s, pair, video.parent, c)

    assert path() == video
    others = {
        path(pair=(7, 27)),
        path(pair=(17, 7)),
        path(c=MediaConfig(size_px=SIZE, fps=5)),
        path(c=MediaConfig(size_px=SIZE + 2)),
        path(s=make_scenario(4, STEPS)),  # same id, different tracks
    }
    assert video not in others and len(others) == 5
    assert all(p.parent == video.parent and p.name.startswith("toy-") for p in others)


def test_a_different_pair_renders_a_different_file(tmp_path: Path) -> None:
    scenario = make_scenario(3, 8, scenario_id="a/b c:1")
    cfg = MediaConfig(size_px=64)
    first = window_video(scenario, (7, 17), tmp_path, cfg)
    second = window_video(scenario, (17, 27), tmp_path, cfg)
    assert first != second and first.is_file() and second.is_file()
    for p in (first, second):
        assert p.parent == tmp_path and p.name.startswith("a_b_c_1-")
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([first.name, second.name])


def test_threads_render_one_file_once(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    scenario = make_scenario(2, 6, scenario_id="threads")
    calls = []
    real = media.save_video

    def slow_save(*args: object, **kwargs: object) -> int:
        calls.append(1)
        time.sleep(0.2)  # long enough for the other threads to find the file missing
        return real(*args, **kwargs)

    monkeypatch.setattr(media, "save_video", slow_save)
    results: list[Path] = []
    threads = [
        threading.Thread(target=lambda: results.append(window_video(scenario, (7,), tmp_path, MediaConfig(64))))
        for _ in range(4)
    ]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    assert len(calls) == 1
    assert len(results) == 4 and len(set(results)) == 1 and results[0].is_file()


def test_bad_input_is_refused(scenario: Scenario, tmp_path: Path) -> None:
    with pytest.raises(InputError, match="track id 99"):
        window_video(scenario, (7, 99), tmp_path, MediaConfig(64))
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(InputError, match="even"):
        MediaConfig(size_px=641)
    with pytest.raises(InputError, match="fps"):
        MediaConfig(fps=0)


def test_agent_positions_are_json_ready(scenario: Scenario, config: MediaConfig) -> None:
    pos = agent_positions(scenario, config)
    assert json.loads(json.dumps(pos)) == pos
    assert (pos["size_px"], pos["steps"], pos["fps"]) == (SIZE, STEPS, 10)
    assert [a["id"] for a in pos["agents"]] == [7, 17, 27, 37]
    assert [a["type"] for a in pos["agents"]] == ["vehicle", "pedestrian", "cyclist", "other"]
    late = pos["agents"][2]["px"]
    assert len(late) == STEPS and late[: STEPS // 3] == [None] * (STEPS // 3)
    assert all(p is not None for p in late[STEPS // 3 :])
    for agent in pos["agents"]:
        for p in agent["px"]:
            if p is not None:
                assert all(0 < v < SIZE and round(v, 1) == v for v in p)


def colour_box_centre(image: np.ndarray, colour: np.ndarray, tol: float = 12.0) -> tuple[float, float] | None:
    """Centre (x, y), in continuous pixel coordinates, of the bounding box of the pixels of `colour`."""
    ys, xs = np.nonzero(np.linalg.norm(image.astype(np.float64) - colour, axis=-1) < tol)
    if len(xs) == 0:
        return None
    return (xs.min() + xs.max() + 1) / 2.0, (ys.min() + ys.max() + 1) / 2.0


def test_agent_positions_match_the_rendered_boxes(scenario: Scenario, config: MediaConfig) -> None:
    """Each agent is the only one of its fill colour: the box of that colour in a frame rendered with the
    video's camera (fixed over every step) is centred on the computed position, within pixel rounding.
    (render_frame would frame only its own step, so the renderer is asked for all steps here.)"""
    pos = agent_positions(scenario, config)
    faces = face_colors(scenario)
    checked = 0
    render = RenderConfig(size_px=SIZE, show_ids=False, trail_steps=0)
    with TopDownRenderer(scenario, render) as renderer:
        for step in (0, STEPS // 2, STEPS - 1):
            image = renderer.frame(step)
            for agent, face in zip(pos["agents"], faces, strict=True):
                centre = colour_box_centre(image, face)
                expected = agent["px"][step]
                if expected is None:
                    assert centre is None, f"agent {agent['id']} is drawn at step {step} but has no position"
                    continue
                assert centre is not None, f"agent {agent['id']} not found in frame {step}"
                assert math.dist(centre, expected) < 0.75, (agent["id"], step, centre, expected)
                checked += 1
    assert checked == 11  # 4 agents at 3 steps, less agent 27 at step 0


def test_agent_positions_match_the_video_frames(scenario: Scenario, config: MediaConfig, video: Path) -> None:
    """In the decoded video (ids written, pair highlighted, H.264 colours shifted by a few tens of levels),
    most of the 3 x 3 pixels around each computed position (the centre one may lie under the dark
    heading tick) are nearest to that agent's fill colour among all agents' fills and the background,
    and most around the position mirrored through the image centre are not."""
    pos = agent_positions(scenario, config)
    faces = face_colors(scenario)
    palette = np.vstack([faces, np.array(to_rgb(style.BACKGROUND)) * 255.0])
    frames = iio.imread(video, index=None).astype(np.float64)

    def votes(step: int, x: int, y: int, agent: int) -> int:
        patch = frames[step, y - 1 : y + 2, x - 1 : x + 2].reshape(-1, 1, 3)
        return int((np.argmin(np.linalg.norm(patch - palette, axis=-1), axis=1) == agent).sum())

    checked = mirrored = 0
    for step in range(0, STEPS, 3):
        for a, agent in enumerate(pos["agents"]):
            p = agent["px"][step]
            if p is None:
                continue
            x, y = int(p[0]), int(p[1])
            assert votes(step, x, y, a) >= 5, (agent["id"], step)
            checked += 1
            mx, my = SIZE - 1 - x, SIZE - 1 - y  # where an axis-convention error could put it
            if math.hypot(mx - x, my - y) > 12:
                assert votes(step, mx, my, a) < 5, (agent["id"], step)
                mirrored += 1
    assert checked == 4 * 7 - 2  # agent 27 is invalid at steps 0 and 3
    assert mirrored >= checked - 2


def test_nearest_agent(scenario: Scenario, config: MediaConfig) -> None:
    pos = agent_positions(scenario, config)
    step = STEPS - 1
    for agent in pos["agents"]:
        x, y = agent["px"][step]
        assert nearest_agent(pos, step, x + 3.0, y - 4.0) == agent["id"]
    assert nearest_agent(pos, step, 0.0, 0.0) is None
    x, y = pos["agents"][2]["px"][step]
    assert nearest_agent(pos, step, x, y) == 27
    assert nearest_agent(pos, 0, x, y) != 27  # not valid at step 0
    assert nearest_agent(pos, STEPS, x, y) is None
    assert nearest_agent(pos, -1, x, y) is None

    toy = {"steps": 1, "agents": [{"id": 1, "px": [[10.0, 10.0]]}, {"id": 2, "px": [[50.0, 10.0]]},
                                  {"id": 3, "px": [None]}]}  # fmt: skip
    assert nearest_agent(toy, 0, 29.0, 10.0) == 1
    assert nearest_agent(toy, 0, 31.0, 10.0) == 2
    assert nearest_agent(toy, 0, 10.0, 40.0) is None  # 30 px away
    assert nearest_agent(toy, 0, 10.0, 40.0, max_px=30.0) == 1
    assert nearest_agent(toy, 0, 90.0, 10.0, max_px=39.0) is None
