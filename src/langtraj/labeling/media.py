"""Media of the labeling tool: each window's top-down MP4 (ids written, candidate pair highlighted),
rendered once and cached, and every agent's pixel position in it for click-to-select (docs/labeling.md)."""

from __future__ import annotations

import hashlib
import json
import math
import re
import threading
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from langtraj.errors import InputError
from langtraj.scenario.model import Scenario
from langtraj.scenario.types import AgentType
from langtraj.viz import RenderConfig, save_video
from langtraj.viz.camera import Camera

MEDIA_VERSION = 1
"""Part of every cache key: raise it when the look of the videos changes, so cached files render anew."""

KEY_CHARS = 16
"""Hex digits of the cache key in a video's file name."""


@dataclass(frozen=True)
class MediaConfig:
    """How the labeling videos are rendered (the cache folder is passed separately).

    size_px: width and height of the square video in pixels; even, because H.264 with 4:2:0 chroma
        needs even sides (an odd size would be padded by a pixel and no longer match `agent_positions`).
    fps: frames per second of the video; one frame per scenario step.
    text_scale: text and lines relative to the renderer's default (dpi size_px / 8): larger, so that
        every agent's id stays legible in a busy intersection; the same proportions at any size.
    """

    size_px: int = 640
    fps: float = 10.0
    text_scale: float = 1.6

    def __post_init__(self) -> None:
        problems = []
        if int(self.size_px) != self.size_px or self.size_px < 16 or int(self.size_px) % 2:
            problems.append(f"size_px must be an even integer >= 16, got {self.size_px!r}")
        if not (math.isfinite(self.fps) and self.fps > 0):
            problems.append(f"fps must be positive, got {self.fps!r}")
        if not (math.isfinite(self.text_scale) and self.text_scale > 0):
            problems.append(f"text_scale must be positive, got {self.text_scale!r}")
        if problems:
            raise InputError("; ".join(problems), where="media config")
        object.__setattr__(self, "size_px", int(self.size_px))
        object.__setattr__(self, "fps", float(self.fps))


def render_config(config: MediaConfig, pair: tuple[int, ...] = (), caption: str | None = None) -> RenderConfig:
    """The renderer's options for a labeling video; `agent_positions` uses the same framing (fixed camera
    over every step, RenderConfig's default margin), so its pixels match the video's."""
    return RenderConfig(
        size_px=config.size_px,
        dpi=config.size_px / 8.0 * config.text_scale,
        fps=config.fps,
        follow_track_id=None,
        show_ids=True,
        highlight_ids=tuple(int(i) for i in pair),
        caption=caption,
    )


def pair_caption(scenario: Scenario, pair: tuple[int, ...]) -> str:
    """First caption line of a window's video: the scenario id and the candidate agents."""
    agents = " and ".join(f"@{int(i)}" for i in pair)
    return f"{scenario.scenario_id}: {agents}" if agents else str(scenario.scenario_id)


def safe_name(scenario_id: str) -> str:
    """`scenario_id` with every character outside [A-Za-z0-9._-] replaced by '_' (never empty)."""
    return re.sub(r"[^A-Za-z0-9._-]", "_", str(scenario_id)) or "_"


def cache_key(scenario: Scenario, pair: tuple[int, ...], config: MediaConfig) -> str:
    """Short hash of what a video shows: scenario id, a digest of its agents' tracks (so a changed window
    under the same id renders anew), the pair, the config and MEDIA_VERSION."""
    agents = scenario.agents
    tracks = hashlib.sha256()
    for array in (agents.ids, agents.types, agents.valid, agents.states):
        arr = np.ascontiguousarray(array)
        tracks.update(str((arr.dtype.str, arr.shape)).encode())
        tracks.update(arr.tobytes())
    blob = json.dumps(
        {
            "scenario_id": str(scenario.scenario_id),
            "tracks": tracks.hexdigest(),
            "pair": [int(i) for i in pair],
            "config": asdict(config),
            "version": MEDIA_VERSION,
        },
        sort_keys=True,
    )
    return hashlib.sha256(blob.encode()).hexdigest()[:KEY_CHARS]


def video_path(scenario: Scenario, pair: tuple[int, ...], cache_dir: Path, config: MediaConfig) -> Path:
    """Where `window_video` caches the video of `scenario` with `pair` highlighted."""
    return Path(cache_dir) / f"{safe_name(scenario.scenario_id)}-{cache_key(scenario, pair, config)}.mp4"


_locks: dict[str, threading.Lock] = {}
_locks_guard = threading.Lock()


def _lock_for(path: Path) -> threading.Lock:
    """The lock of one cached file (one per path, kept for the life of the process: a few bytes each)."""
    key = str(path.resolve())
    with _locks_guard:
        lock = _locks.get(key)
        if lock is None:
            lock = _locks[key] = threading.Lock()
        return lock


def window_video(scenario: Scenario, pair: tuple[int, ...], cache_dir: Path, config: MediaConfig) -> Path:
    """The H.264 MP4 of every step of `scenario` (fixed camera, every agent's id written, `pair`
    highlighted), rendered on first use and cached in `cache_dir`; later calls return the cached file.

    Concurrency: threads of one process rendering the same file wait on a per-file lock, so it is
    rendered once. Across processes there is no lock: two processes may both render a missing file,
    but `save_video` writes to a temporary file and renames it into place, so the cached file is only
    ever absent or complete (the later rename replaces an identical video).
    """
    pair = tuple(int(i) for i in pair)
    for tid in pair:
        try:
            scenario.agents.index_of(tid)
        except KeyError:
            raise InputError(f"track id {tid} is not in the scene", where=scenario.scenario_id) from None
    path = video_path(scenario, pair, Path(cache_dir), config)
    if path.is_file():
        return path
    with _lock_for(path):
        if not path.is_file():  # another thread may have rendered it while this one waited
            rc = render_config(config, pair, caption=pair_caption(scenario, pair))
            save_video(scenario, path, rc, progress=False)
    return path


def _type_name(agent_type: int) -> str:
    try:
        return AgentType(int(agent_type)).name.lower()
    except ValueError:
        return AgentType.OTHER.name.lower()


def agent_positions(scenario: Scenario, config: MediaConfig) -> dict[str, Any]:
    """Every agent's centre in the pixels of `window_video`'s frames, for click-to-select (JSON-ready).

    {"size_px": N, "steps": T, "fps": fps, "agents": [{"id": track_id, "type": "vehicle", "px":
    [[x, y] or None for each step]}]}: x to the right and y down from the image's top-left corner,
    in pixels (continuous: pixel column i spans [i, i + 1)), rounded to 0.1; None where the agent is
    not valid. The renderer's axes fill the square figure and its fixed camera frames every step, so
    the mapping from metres is linear with the camera's limits (taken from the same Camera).
    """
    rc = render_config(config)
    steps = range(scenario.num_steps)
    camera = Camera(scenario, steps, follow_index=None, view_extent_m=rc.view_extent_m, margin_m=rc.margin_m)
    x0, x1, y0, y1 = camera.limits(0)
    n = config.size_px
    agents = scenario.agents
    xy = agents.xy.astype(np.float64)
    px = np.stack([(xy[..., 0] - x0) / (x1 - x0) * n, (y1 - xy[..., 1]) / (y1 - y0) * n], axis=-1)
    show = agents.valid & np.isfinite(px).all(axis=-1)
    px = np.round(px, 1)
    out = []
    for a in range(agents.num_agents):
        track = [[float(px[a, t, 0]), float(px[a, t, 1])] if show[a, t] else None for t in steps]
        out.append({"id": int(agents.ids[a]), "type": _type_name(agents.types[a]), "px": track})
    return {"size_px": n, "steps": scenario.num_steps, "fps": config.fps, "agents": out}


def nearest_agent(positions: dict[str, Any], step: int, x: float, y: float, max_px: float = 25) -> int | None:
    """The track id whose centre at `step` (in `agent_positions`' pixels) is nearest to the click (x, y),
    if within `max_px`; None when no agent is that close or `step` is outside the window."""
    if not 0 <= int(step) < int(positions["steps"]):
        return None
    best, best_d = None, math.inf
    for agent in positions["agents"]:
        pos = agent["px"][int(step)]
        if pos is None:
            continue
        d = math.hypot(pos[0] - x, pos[1] - y)
        if d <= max_px and (best is None or d < best_d):
            best, best_d = int(agent["id"]), d
    return best
