"""Vehicles pulling out in front of another, for the interaction detector (docs/interdrive.md, 'Interaction labels').

A vehicle (or cyclist) pulls out in front of another where it comes onto the other's heading line (within
`pull_out_on_line`) ahead of it, its rear past the other's front; having been, within `pull_out_lookback_s` before,
(nearly) standing (at most `pull_out_speed`), off that line (farther than `red_conflict_radius`) and either heading
across it (by `pull_out_heading` or more) or on no map lane: waiting at a side road's mouth, in a driveway or at the
kerb. When it set off (the last such step), the other drove at `pull_out_other_speed` or more, and the gap when it
comes onto the line is at most `foe_horizon_s` at that speed (or `red_foe_range`): the other may brake for it
after, as it should. A car already in the lane beside, or queued ahead in the same lane,
does not pull out (NHTSA's pre-crash scenarios of a vehicle turning or crossing at a non-signalized junction).
"""

from __future__ import annotations

import numpy as np

from langtraj.angles import wrap_angle
from langtraj.interdrive.detector.arrays import SceneArrays
from langtraj.interdrive.detector.lanes import LaneGeometry
from langtraj.interdrive.detector.parts import Pair, ScenePart
from langtraj.runs import true_runs
from langtraj.scenario.model import STEP_SECONDS


class PullOutGeometry(ScenePart):
    """Who pulls out in front of whom (`runs`), from the two agents' tracks and `lanes`' per-step lane matches."""

    def __init__(self, arrays: SceneArrays, lanes: LaneGeometry):
        super().__init__(arrays)
        self.lanes = lanes
        self._off_lanes: dict[int, np.ndarray] = {}

    def off_lanes(self, a: int) -> np.ndarray:
        """bool [T]: agent `a` is on no map lane at each step (computed once per agent: every other agent's pull-out
        asks)."""
        if a not in self._off_lanes:
            self._off_lanes[a] = self.lanes.lanes_at(a, np.arange(self.num_steps)) < 0
        return self._off_lanes[a]

    def could_pull_out(self, a: int) -> bool:
        """Whether `a` is a mover that is (nearly) standing at some valid step: only such agents can pull out."""
        return bool(self.movers[a] and (self.valid[a] & (self.speed[a] <= self.config.pull_out_speed)).any())

    def runs(self, a: int, b: int) -> list[Pair]:
        """Agent `a` pulls out in front of agent `b` (see the module): from the last step it was slow and off `b`'s
        line before coming onto it, to `braking_response_s` after (the time `b` has to brake); empty when it does
        not."""
        cfg = self.config
        if a == b or not self.movers[b] or not self.could_pull_out(a):
            return []
        both = self.valid[a] & self.valid[b]
        if not both.any():
            return []
        rel = self.xy[a] - self.xy[b]
        cos, sin = np.cos(self.heading[b]), np.sin(self.heading[b])
        along, side = rel[:, 0] * cos + rel[:, 1] * sin, rel[:, 1] * cos - rel[:, 0] * sin
        clear = along - 0.5 * (self.length[a] + self.length[b])
        on_line = both & (np.abs(side) <= cfg.pull_out_on_line) & (clear > 0.0)
        across = np.abs(wrap_angle(self.heading[a] - self.heading[b])) >= cfg.pull_out_heading
        waiting = both & (np.abs(side) > cfg.red_conflict_radius) & (self.speed[a] <= cfg.pull_out_speed)
        waiting &= across | self.off_lanes(a)
        lookback = round(cfg.pull_out_lookback_s / STEP_SECONDS)
        response = round(cfg.braking_response_s / STEP_SECONDS)
        out: list[Pair] = []
        for entry, _ in true_runs(on_line):
            before = np.flatnonzero(waiting[max(entry - lookback, 0) : entry])
            if entry == 0 or not before.size:
                continue
            start = max(entry - lookback, 0) + int(before[-1])
            other = self.speed[b, start]  # when it set off: the other may brake for it after
            reach = max(cfg.foe_horizon_s * other, cfg.red_foe_range)
            if other >= cfg.pull_out_other_speed and clear[entry] <= reach:
                out.append(Pair(a, b, start, min(entry + response, self.num_steps)))
        return out
