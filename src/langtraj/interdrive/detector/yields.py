"""Vehicles yielding to vehicles for the interaction detector (docs/interdrive.md, 'Interaction labels'):
held steps, red lights, conflict points of crossing paths, and the yield runs.
"""

from __future__ import annotations

from functools import cached_property

import numpy as np

from langtraj.angles import wrap_angle
from langtraj.interdrive.detector.arrays import SceneArrays
from langtraj.interdrive.detector.lanes import LaneGeometry
from langtraj.interdrive.detector.parts import Pair, ScenePart
from langtraj.interdrive.detector.paths import PathGeometry
from langtraj.runs import true_runs
from langtraj.scenario.types import TrafficLightState


class YieldGeometry(ScenePart):
    """Which vehicle is held back, and which waits for whom where their paths cross (over the `paths` and map
    `lanes` of the scene)."""

    def __init__(self, arrays: SceneArrays, paths: PathGeometry, lanes: LaneGeometry):
        super().__init__(arrays)
        self.paths = paths
        self.lanes = lanes

    @cached_property
    def red(self) -> np.ndarray:
        """[A, T]: the agent's lane leads only into signalled links none of which shows go (waiting at a red
        light is no yield), or a stop point with a non-go signal lies just ahead of its front."""
        lights = self.scenario.traffic_lights
        out = np.zeros(self.valid.shape, bool)
        if lights.num_lanes == 0:
            return out
        go = np.isin(lights.states, [TrafficLightState.GO, TrafficLightState.ARROW_GO]) | ~lights.valid  # [T, L]
        column = {int(lane): c for c, lane in enumerate(lights.lane_ids)}
        steps = np.arange(self.num_steps)
        for lane in self.scenario.road_map.lanes:
            cols = [column[n] for n in (lane.id, *lane.exit_lanes) if n in column]
            if cols:
                on = self.lanes.per_step == lane.id
                out |= on & ~go[:, cols].any(axis=1)[steps][None, :]
        stops = lights.stop_points[:, :2]
        rel = stops[None, None, :, :] - self.xy[:, :, None, :]  # [A, T, L, 2]
        cos, sin = np.cos(self.heading)[..., None], np.sin(self.heading)[..., None]
        along = rel[..., 0] * cos + rel[..., 1] * sin - 0.5 * self.length[..., None]
        lateral = np.abs(rel[..., 1] * cos - rel[..., 0] * sin)
        near = (along > -1.0) & (along < self.config.red_distance) & (lateral < 2.0)
        return (out | (near & ~go[None]).any(axis=-1)) & self.valid

    @cached_property
    def held(self) -> np.ndarray:
        """[A, T]: slow or braking, valid, and not waiting at a red light."""
        cfg = self.config
        slow = (self.speed < cfg.held_speed) | (self.accel < cfg.braking)
        return slow & self.valid & ~self.red

    def _branches(self, a: int) -> list[tuple[np.ndarray, np.ndarray]]:
        """a's possible paths from its first valid step: its trajectory extended straight by `wait_extension`; for
        a vehicle standing all window (its way on is unknown), its lane and each chain of successor lanes instead
        (`LaneGeometry.continuations`, none on a signal-controlled approach); points [N, 2] and headings [N]."""
        path = self.paths.waiting[a]
        real = path.points[path.real]
        last = np.flatnonzero(self.valid[a])[-1]
        continue_on = self.config.continue_on_map and self.static[a] and self.held[a, last]
        conts = self.lanes.continuations(a) if continue_on else []
        if not conts:
            return [(path.points, path.heading)]
        out = []
        for cont in conts:
            pts = np.concatenate([real, cont])
            d = np.gradient(pts, axis=0) if len(pts) > 1 else np.zeros((1, 2))
            out.append((pts, np.arctan2(d[:, 1], d[:, 0])))
        return out

    def _conflict_point(self, branch: tuple[np.ndarray, np.ndarray], b: int) -> np.ndarray | None:
        """The first point of `branch` that b's path (trajectory and straight extension) crosses."""
        cfg = self.config
        pa, ha = branch
        path_b = self.paths.driven[b]
        ahead = path_b.arc >= 0.0
        pb, hb = path_b.points[ahead], path_b.heading[ahead]
        if not len(pa) or not len(pb):
            return None
        d = np.linalg.norm(pa[:, None, :] - pb[None, :, :], axis=-1)
        crossing = (d < cfg.conflict_radius) & (np.abs(wrap_angle(ha[:, None] - hb[None, :])) > cfg.conflict_heading)
        rows = np.flatnonzero(crossing.any(axis=1))
        return pa[rows[0]] if rows.size else None

    def _yield_mask(self, a: int, b: int, point: np.ndarray) -> np.ndarray | None:
        """Steps at which a is held before `point` while b, which gets there first, is near it."""
        cfg = self.config
        steps = np.arange(self.num_steps)
        at_a = np.flatnonzero(self.valid[a] & (np.linalg.norm(self.xy[a] - point, axis=1) < cfg.conflict_radius))
        reach_a = int(at_a[0]) if at_a.size else self.num_steps
        dist_b = np.linalg.norm(self.xy[b] - point, axis=1)
        inside_b = self.valid[b] & (dist_b < cfg.conflict_radius + 0.5 * self.length[b])
        entered = np.flatnonzero(inside_b)
        if entered.size:
            first_in, last_in = int(entered[0]), int(entered[-1])
        else:
            last_b = np.flatnonzero(self.valid[b])
            if last_b.size == 0 or last_b[-1] < self.num_steps - 1:
                return None
            eta = dist_b[last_b[-1]] / max(self.speed[b, last_b[-1]], 1.0)
            if eta > cfg.foe_horizon_s:
                return None
            first_in = last_in = self.num_steps
        if first_in > reach_a or (first_in == reach_a and reach_a < self.num_steps):
            return None
        approaching = (dist_b / np.maximum(self.speed[b], 1.0) <= cfg.foe_horizon_s) & ~self.held[b]
        near = self.valid[b] & (steps <= last_in) & (approaching | inside_b)
        return self.held[a] & near & (steps < reach_a) & ~self._queued(a, point)

    def _queued(self, a: int, point: np.ndarray) -> np.ndarray:
        """[T]: a's leader (on a's path) is between a and `point`, so a waits behind it, not for a foe."""
        lead = self.paths.leaders[a]
        out = np.zeros(self.num_steps, bool)
        steps = np.flatnonzero(lead >= 0)
        if not steps.size:
            return out
        to_point = np.linalg.norm(point - self.xy[a, steps], axis=1)
        to_lead = np.linalg.norm(self.xy[lead[steps], steps] - self.xy[a, steps], axis=1)
        out[steps] = to_lead < to_point
        return out

    def _candidate_pairs(self) -> list[tuple[int, int]]:
        """Ordered mover pairs whose trajectory boxes (grown by the wait extension) overlap."""
        paths = self.paths.driven
        keys = sorted(paths)
        grow = self.config.wait_extension + self.config.conflict_radius
        boxes = {}
        for a in keys:
            real = paths[a].points[paths[a].arc >= 0.0]
            boxes[a] = (real.min(axis=0) - grow, real.max(axis=0) + grow)
        return [
            (a, b)
            for a in keys
            for b in keys
            if a != b and (boxes[a][0] <= boxes[b][1]).all() and (boxes[b][0] <= boxes[a][1]).all()
        ]

    @cached_property
    def vehicle_yields(self) -> list[Pair]:
        """A (held before the conflict point) yields to B (reaching it first) where their paths cross. A parked car
        yields to no one, and no one yields to a car standing all window (it never goes first)."""
        cfg = self.config
        out = []
        branches: dict[int, list[tuple[np.ndarray, np.ndarray]]] = {}
        for a, b in self._candidate_pairs():
            if not self.held[a].any() or self.parked[a] or self.static[b]:
                continue
            if a not in branches:
                branches[a] = self._branches(a)
            mask = np.zeros(self.num_steps, bool)
            for branch in branches[a]:
                point = self._conflict_point(branch, b)
                found = None if point is None else self._yield_mask(a, b, point)
                if found is not None:
                    mask |= found
            out.extend(Pair(a, b, s, e) for s, e in true_runs(mask, cfg.min_event_steps, cfg.merge_gap))
        return out
