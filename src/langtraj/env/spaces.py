"""The observation and action spaces of the LangTraj environment (docs/testing.md, 'Observations' and 'Actions').

Everything a planner sees is ego-centred: x forward along the ego's heading, y to its left, headings relative to
the ego's, metres and seconds. Fixed sizes (the nearest `NUM_AGENTS` agents, `NUM_POLYLINES` map polylines of
`POLYLINE_POINTS` points within `MAP_RADIUS_M`, ...) with explicit validity masks, so every observation fits one
`gymnasium.spaces.Dict`. The keys and columns are named here once; planners and the JSON-lines protocol read them
from here.
"""

from __future__ import annotations

from enum import IntEnum
from typing import Any

import numpy as np
from gymnasium import spaces

from langtraj.angles import wrap_angle

NUM_AGENTS = 16
"""The nearest other agents in an observation (by distance between centres)."""
AGENT_RADIUS_M = 80.0
"""Agents farther than this from the ego are left out."""
NUM_ROUTE_POINTS = 50
ROUTE_SPACING_M = 2.0
"""The route ahead: `NUM_ROUTE_POINTS` points every `ROUTE_SPACING_M` m from the ego's projection onto it, each
with the speed limit of its lane (`route_speed_limit`, m/s; 0 where the map gives none or off the route)."""
NUM_POLYLINES = 64
POLYLINE_POINTS = 20
MAP_RADIUS_M = 60.0
"""Map polylines (lane centres, road lines and edges, crosswalks, ...) with a point within `MAP_RADIUS_M`: the
`NUM_POLYLINES` nearest, each cut to the points within the radius and resampled to `POLYLINE_POINTS` points."""
NUM_LIGHTS = 16
"""The nearest traffic-light stop points."""
HISTORY_STEPS = 10
"""The others' last second: `agents_history` holds each listed agent's positions at the 10 steps before this one
(ego frame of now, oldest first; `agents_history_valid` where it was seen)."""


class EgoColumn(IntEnum):
    """Columns of `ego`, read by name (`observation["ego"][EgoColumn.SPEED]`): its world pose (x, y, heading: the
    only world-frame values, for planners that keep a map of their own), speed (m/s), the acceleration and yaw rate
    it executed last step, and its box."""

    X = 0
    Y = 1
    HEADING = 2
    SPEED = 3
    ACCELERATION = 4
    YAW_RATE = 5
    LENGTH = 6
    WIDTH = 7


class AgentColumn(IntEnum):
    """Columns of `agents` (ego frame), read by name (`observation["agents"][:, AgentColumn.VX]`)."""

    X = 0
    Y = 1
    HEADING = 2
    VX = 3
    VY = 4
    LENGTH = 5
    WIDTH = 6


MAX_ACCEL = 8.0
MAX_YAW_RATE = 1.5
"""Bounds of the control action, those of the model's unicycle (`langtraj.model.dynamics.Unicycle`)."""
TRAJECTORY_POSES = 10
"""Poses (x, y, heading; ego frame) of a trajectory action, every 0.1 s from the next step."""
TRAJECTORY_BOUND_M = 100.0
"""Bound of a trajectory action's x and y (m); its headings lie in [-pi, pi]."""
ACTION_KINDS = ("control", "trajectory")

WORLD_BOUND_M = 1e7
"""Bound of world coordinates (the ego's pose) in the observation space."""
LOCAL_BOUND = 1e4
"""Bound of ego-frame values (m, m/s, rad) and of times (s) in the observation space."""
_MAX_ID = 2**62  # track ids are int64; a bound gymnasium can sample within


def _box(*shape: int, bound: float = LOCAL_BOUND) -> spaces.Box:
    return spaces.Box(-bound, bound, shape=shape, dtype=np.float32)


def observation_space() -> spaces.Dict:
    """The space every observation lies in."""
    return spaces.Dict(
        {
            "ego": _box(len(EgoColumn), bound=WORLD_BOUND_M),
            "time": spaces.Box(0.0, LOCAL_BOUND, shape=(1,), dtype=np.float32),
            "route": _box(NUM_ROUTE_POINTS, 2),
            "route_valid": spaces.MultiBinary(NUM_ROUTE_POINTS),
            "route_speed_limit": spaces.Box(0.0, LOCAL_BOUND, shape=(NUM_ROUTE_POINTS,), dtype=np.float32),
            "agents": _box(NUM_AGENTS, len(AgentColumn)),
            "agents_id": spaces.Box(-1, _MAX_ID, shape=(NUM_AGENTS,), dtype=np.int64),
            "agents_type": spaces.Box(0, 4, shape=(NUM_AGENTS,), dtype=np.int64),
            "agents_valid": spaces.MultiBinary(NUM_AGENTS),
            "agents_history": _box(NUM_AGENTS, HISTORY_STEPS, 2),
            "agents_history_valid": spaces.MultiBinary((NUM_AGENTS, HISTORY_STEPS)),
            "map": _box(NUM_POLYLINES, POLYLINE_POINTS, 2),
            "map_type": spaces.Box(0, 255, shape=(NUM_POLYLINES,), dtype=np.int64),
            "map_valid": spaces.MultiBinary((NUM_POLYLINES, POLYLINE_POINTS)),
            "lights": _box(NUM_LIGHTS, 2),
            "lights_state": spaces.Box(0, 8, shape=(NUM_LIGHTS,), dtype=np.int64),
            "lights_valid": spaces.MultiBinary(NUM_LIGHTS),
        }
    )


def action_space(kind: str = "control") -> spaces.Box:
    """`control`: (acceleration m/s^2, yaw rate rad/s) for the next 0.1 s; `trajectory`: `TRAJECTORY_POSES` poses
    (x, y, heading) in the current ego frame, 0.1 s apart, followed by the tracker (docs/testing.md, 'Actions')."""
    if kind == "control":
        return spaces.Box(
            np.array([-MAX_ACCEL, -MAX_YAW_RATE], np.float32),
            np.array([MAX_ACCEL, MAX_YAW_RATE], np.float32),
            dtype=np.float32,
        )
    if kind == "trajectory":
        bound = np.array([TRAJECTORY_BOUND_M, TRAJECTORY_BOUND_M, np.pi], np.float32)
        return spaces.Box(
            np.tile(-bound, (TRAJECTORY_POSES, 1)), np.tile(bound, (TRAJECTORY_POSES, 1)), dtype=np.float32
        )
    raise ValueError(f"action must be one of {', '.join(ACTION_KINDS)}, got {kind!r}")


class ActionError(ValueError):
    """An action that is not one of its action space's; its message says how, as "an action of shape (3,), expected
    (2,)" (each caller says who gave it and when)."""


def checked_action(action: Any, kind: str) -> np.ndarray:
    """`action` as a float64 array of the `kind` action space's shape: the one check of a planner's action (the env,
    a suite's episode, the JSON-lines protocol); raises ActionError for anything not numeric, of another shape, not
    finite, or (a trajectory) with a pose beyond the space's `TRAJECTORY_BOUND_M`. A trajectory's headings are
    wrapped to (-pi, pi]; a control is not bounded here: the env clips it to the unicycle's bounds."""
    try:
        values = np.asarray(action, np.float64)
    except (TypeError, ValueError):
        raise ActionError(f"an action that is not an array of numbers ({type(action).__name__})") from None
    expected = action_space(kind).shape
    if values.shape != expected:
        raise ActionError(f"an action of shape {values.shape}, expected {expected}")
    if not np.isfinite(values).all():
        raise ActionError("a non-finite action")
    if kind == "trajectory":
        far = np.abs(values[:, :2]).max(axis=1)
        if (far > TRAJECTORY_BOUND_M).any():
            k = int(np.argmax(far > TRAJECTORY_BOUND_M))
            raise ActionError(
                f"a trajectory pose {k} {far[k]:.1f} m from the ego, beyond the space's {TRAJECTORY_BOUND_M:g} m"
            )
        values = values.copy()
        values[:, 2] = wrap_angle(values[:, 2])
    return values
