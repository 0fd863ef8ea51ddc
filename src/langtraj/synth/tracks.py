"""Turning SUMO's raw per-step reports into clean tracks in the Scenario conventions.

Each agent gets a track id in order of first appearance (deterministic), box centres from the front
bumper, headings in radians (repaired by `smoothing`), velocity along the heading at SUMO's speed, and
its lane and leader per step. Steps where the agent was teleported are invalid.

See docs/data.md.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from langtraj.scenario.types import AgentType
from langtraj.synth.convert import centre_from_front, heading_from_sumo_angle
from langtraj.synth.records import RawTrack, Track
from langtraj.synth.smoothing import limit_yaw_rate, smooth_pedestrian


def _dense(raw: RawTrack) -> tuple[int, np.ndarray, np.ndarray, np.ndarray]:
    steps = np.asarray(raw.steps, np.int64)
    start = int(steps[0])
    n = int(steps[-1]) - start + 1
    idx = steps - start
    valid = np.zeros(n, bool)
    valid[idx] = True
    rows = np.full((n, 4), np.nan)
    rows[idx] = np.asarray(raw.rows, np.float64)
    lanes = np.full(n, -1, np.int32)
    lanes[idx] = raw.lanes
    return start, valid, rows, lanes


def _fill_invalid(values: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Invalid rows take the last valid value (teleport gaps), so smoothing never sees NaN."""
    if valid.all():
        return values
    last = np.maximum.accumulate(np.where(valid, np.arange(len(valid)), 0))
    return values[last]


def build_track(raw: RawTrack, track_id: int, leader_ids: dict[str, int]) -> Track:
    """A clean `Track` from one agent's raw reports."""
    start, valid, rows, lanes = _dense(raw)
    rows = _fill_invalid(rows, valid)
    sumo_heading = heading_from_sumo_angle(rows[:, 2])
    speed = rows[:, 3]
    xy = centre_from_front(rows[:, :2], sumo_heading, raw.length)
    if raw.agent_type == AgentType.PEDESTRIAN:
        xy, heading = smooth_pedestrian(xy, sumo_heading)
    else:
        heading = limit_yaw_rate(sumo_heading, speed)
    leader = np.full(len(valid), -1, np.int64)
    gap = np.full(len(valid), np.nan, np.float32)
    idx = np.asarray(raw.steps, np.int64) - start
    leader[idx] = [leader_ids.get(name, -1) for name in raw.leaders]
    gap[idx] = raw.gaps
    gap[leader < 0] = np.nan
    return Track(
        track_id=track_id,
        sumo_id=raw.sumo_id,
        agent_type=raw.agent_type,
        vtype=raw.vtype,
        size=(raw.length, raw.width, raw.height),
        start=start,
        xy=xy,
        heading=heading,
        speed=speed,
        valid=valid,
        lane=lanes,
        leader=leader,
        gap=gap,
    )


def build_tracks(raws: Sequence[RawTrack]) -> tuple[Track, ...]:
    """Clean tracks for every agent that reported at least one step, ids 1, 2, ... by first step."""
    present = sorted((r for r in raws if r.steps), key=lambda r: (r.steps[0], r.sumo_id))
    ids = {r.sumo_id: i + 1 for i, r in enumerate(present)}
    return tuple(build_track(r, ids[r.sumo_id], ids) for r in present)
