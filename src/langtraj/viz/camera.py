"""Camera: the square window of the world (metres) each frame shows.

Either fixed over all rendered steps (bounds of the valid agent positions plus a margin, or the map
when no agent is valid), or following one agent at a fixed extent.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from langtraj.scenario.model import Scenario

Limits = tuple[float, float, float, float]
"""(xmin, xmax, ymin, ymax) in metres."""

MIN_SPAN_M = 20.0
"""Smallest side of a fixed view, so a scene with one agent is not zoomed onto a point."""

_EMPTY_SPAN_M = 100.0


def square(cx: float, cy: float, span: float) -> Limits:
    """The square window of side `span` centred on (cx, cy)."""
    half = span / 2.0
    return (cx - half, cx + half, cy - half, cy + half)


def map_bounds(scenario: Scenario) -> tuple[np.ndarray, np.ndarray] | None:
    """Min and max (x, y) over all map points, or None for an empty map."""
    pts = [f.points[:, :2] for f in scenario.road_map if len(f.points)]
    if not pts:
        return None
    allp = np.concatenate(pts)
    return allp.min(axis=0), allp.max(axis=0)


def scene_limits(scenario: Scenario, steps: Sequence[int], margin_m: float) -> Limits:
    """A square window over every valid agent position at `steps`, plus `margin_m` on each side;
    the map's bounds when no agent is valid there, and 100 m around the origin for an empty scene."""
    idx = np.asarray(list(steps), np.int64)
    valid = scenario.agents.valid[:, idx]
    if valid.any():
        xy = scenario.agents.xy[:, idx][valid].astype(np.float64)
        lo, hi = xy.min(axis=0) - margin_m, xy.max(axis=0) + margin_m
    else:
        bounds = map_bounds(scenario)
        if bounds is None:
            return square(0.0, 0.0, _EMPTY_SPAN_M)
        lo, hi = bounds
    center = (lo + hi) / 2.0
    span = max(float((hi - lo).max()), MIN_SPAN_M)
    return square(float(center[0]), float(center[1]), span)


def follow_position(scenario: Scenario, agent_index: int, step: int) -> tuple[float, float] | None:
    """Where to centre on an agent at `step`: its position there, else at its nearest valid step
    (so the view holds still while the track is missing), or None when it is never valid."""
    valid = scenario.agents.valid[agent_index]
    steps = np.flatnonzero(valid)
    if len(steps) == 0:
        return None
    nearest = int(steps[np.argmin(np.abs(steps - step))])
    x, y = scenario.agents.xy[agent_index, nearest]
    return float(x), float(y)


class Camera:
    """Answers the view limits of each step: fixed over `steps`, or following one agent."""

    def __init__(
        self,
        scenario: Scenario,
        steps: Sequence[int],
        *,
        follow_index: int | None,
        view_extent_m: float,
        margin_m: float,
    ):
        self._scenario = scenario
        self._follow = follow_index
        self._extent = float(view_extent_m)
        self._fixed: Limits | None = None
        if follow_index is None or follow_position(scenario, follow_index, 0) is None:
            self._follow = None
            self._fixed = scene_limits(scenario, steps, margin_m)

    @property
    def span(self) -> float:
        """Side of the view in metres (the same for every step)."""
        if self._fixed is not None:
            return self._fixed[1] - self._fixed[0]
        return self._extent

    def limits(self, step: int) -> Limits:
        if self._fixed is not None:
            return self._fixed
        assert self._follow is not None
        pos = follow_position(self._scenario, self._follow, step)
        assert pos is not None
        return square(pos[0], pos[1], self._extent)
