"""Red lights run across another agent's path, for the interaction detector (docs/interdrive.md, 'Interaction
labels').

A vehicle runs a red light where its front passes a signal's stop point (within `red_lateral` of its heading line)
while that signal shows stop (red, or a red arrow), and it does so across another road user's path when, more than
`red_conflict_radius` to the side of the user's heading line then, it crosses that line (or comes within 1 m of it)
within `red_crossing_s` after, ahead of the user by at most `foe_horizon_s` at its speed (or `red_foe_range`): the
one who had the right of way and has to give way or brake; or when the user, a vehicle or cyclist, yields to it (the
yield rule's `pair_yields`) within `red_crossing_s` of the run. A leader running the light ahead of the user in its
lane is on its line already, and is not counted.
"""

from __future__ import annotations

from functools import cached_property

import numpy as np

from langtraj.interdrive.detector.arrays import SceneArrays
from langtraj.interdrive.detector.parts import Pair, ScenePart
from langtraj.interdrive.detector.yields import YieldGeometry
from langtraj.scenario.model import STEP_SECONDS
from langtraj.scenario.types import RED_STATES


class RedLightGeometry(ScenePart):
    """Who runs a red light when (`crossings`), and across whose path (`runs`); a yield of the other to the runner
    that the yield rule finds (`YieldGeometry.pair_yields`) around the run counts too."""

    def __init__(self, arrays: SceneArrays, yields: YieldGeometry):
        super().__init__(arrays)
        self.yields = yields
        self._crossings: dict[int, np.ndarray] = {}

    @cached_property
    def _stop(self) -> np.ndarray | None:
        """bool [T, L]: each signal shows stop at each step (None without signals)."""
        lights = self.scenario.traffic_lights
        if lights is None or lights.num_lanes == 0:
            return None
        return np.isin(lights.states[: self.num_steps], [int(s) for s in RED_STATES]) & lights.valid[: self.num_steps]

    def crossings(self, a: int) -> np.ndarray:
        """The steps at which vehicle or cyclist `a`'s front passes the stop point of a signal showing stop (computed
        once per agent: every other agent's run asks)."""
        if a not in self._crossings:
            self._crossings[a] = self._crossings_of(a)
        return self._crossings[a]

    def _crossings_of(self, a: int) -> np.ndarray:
        stop = self._stop
        if stop is None or not self.movers[a]:
            return np.zeros(0, np.int64)
        points = self.scenario.traffic_lights.stop_points[:, :2]
        rel = points[None, :, :] - self.xy[a][:, None, :]  # [T, L, 2]
        cos, sin = np.cos(self.heading[a])[:, None], np.sin(self.heading[a])[:, None]
        ahead = rel[..., 0] * cos + rel[..., 1] * sin - 0.5 * self.length[a][:, None]
        lateral = np.abs(rel[..., 1] * cos - rel[..., 0] * sin)
        both = self.valid[a, :-1] & self.valid[a, 1:]
        passed = (ahead[:-1] > 0.0) & (ahead[1:] <= 0.0) & (lateral[1:] < self.config.red_lateral) & stop[1:]
        return np.flatnonzero(both & passed.any(axis=1)) + 1

    def runs(self, a: int, b: int) -> list[Pair]:
        """Agent `a` runs a red light across agent `b`'s path (see the module): from the step it passes the stop
        point to `red_crossing_s` after (or to the end of `b`'s yield); empty when it does not."""
        cfg = self.config
        if a == b or not self.movers[a] or not self.valid[b].any():
            return []
        window = round(cfg.red_crossing_s / STEP_SECONDS)
        gave_way: list[Pair] | None = None  # the yield rule's runs of b for a, found once and only when needed
        out: list[Pair] = []
        for red in self.crossings(a).tolist():
            if out and red < out[-1].end:
                continue  # the same run past a second stop line
            end = min(red + window, self.num_steps)
            if gave_way is None:
                gave_way = self.yields.pair_yields(b, a) if self.movers[b] else []
            waits = [y for y in gave_way if y.start <= end and y.end >= red - window]
            if waits or self._across(a, b, red, end):
                out.append(Pair(a, b, red, max([end, *(y.end for y in waits)])))
        return out

    def _across(self, a: int, b: int, red: int, end: int) -> bool:
        """Whether `a`, off `b`'s heading line at step `red` (farther than `red_conflict_radius` to its side), crosses
        that line ahead of `b` by at most `foe_horizon_s` at `b`'s speed (or `red_foe_range`) over [red, end)."""
        cfg = self.config
        steps = np.arange(red, end)
        steps = steps[self.valid[a, steps] & self.valid[b, steps]]
        if steps.size < 2:
            return False
        rel = self.xy[a, steps] - self.xy[b, steps]
        cos, sin = np.cos(self.heading[b, steps]), np.sin(self.heading[b, steps])
        along, side = rel[:, 0] * cos + rel[:, 1] * sin, rel[:, 1] * cos - rel[:, 0] * sin
        if abs(side[0]) <= cfg.red_conflict_radius:
            return False  # on its line already: a leader in its lane, not across its path
        reach = np.maximum(cfg.foe_horizon_s * self.speed[b, steps], cfg.red_foe_range)
        ahead = (along > 0.0) & (along <= reach)
        crossed = (np.sign(side[:-1]) != np.sign(side[1:])) | (np.abs(side[1:]) < 1.0)
        return bool((crossed & ahead[1:]).any())
