"""Vehicles yielding to vehicles for the interaction detector (docs/interdrive.md, 'Interaction labels'):
held steps, red lights, conflict points of crossing paths, and the yield runs.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import cached_property
from typing import TypeVar

import numpy as np

from langtraj.angles import wrap_angle
from langtraj.interdrive.detector.arrays import SceneArrays
from langtraj.interdrive.detector.lanes import LaneGeometry
from langtraj.interdrive.detector.parts import Pair, ScenePart
from langtraj.interdrive.detector.paths import PathGeometry
from langtraj.runs import true_runs
from langtraj.scenario.types import TrafficLightState

_T = TypeVar("_T")


class YieldGeometry(ScenePart):
    """Which vehicle is held back, and which waits for whom where their paths cross (over the `paths` and map
    `lanes` of the scene). What one ordered pair needs is computed per agent on first use (`held_of`, and the
    lanes, red lights and leaders only at the steps that decide), so judging one pair (`pair_yields`) reads only
    its two agents and the leader of the waiting one."""

    def __init__(self, arrays: SceneArrays, paths: PathGeometry, lanes: LaneGeometry):
        super().__init__(arrays)
        self.paths = paths
        self.lanes = lanes

    @cached_property
    def _per_agent(self) -> dict[tuple[str, int], object]:
        """Per-agent held rows, branches and boxes, and per-lane red signals, computed so far."""
        return {}

    def _cached(self, kind: str, a: int, compute: Callable[[int], _T]) -> _T:
        """`compute(a)`, computed once per `kind` and agent."""
        key = (kind, a)
        if key not in self._per_agent:
            self._per_agent[key] = compute(a)
        return self._per_agent[key]  # type: ignore[return-value]

    # ------------------------------------------------------------ held vehicles
    @cached_property
    def _go(self) -> np.ndarray | None:
        """[T, L]: signal l shows go (or is unknown) at step t; None without signals."""
        lights = self.scenario.traffic_lights
        if lights.num_lanes == 0:
            return None
        return np.isin(lights.states, [TrafficLightState.GO, TrafficLightState.ARROW_GO]) | ~lights.valid

    @cached_property
    def _columns(self) -> dict[int, int]:
        """Signal column of each signalled map lane id."""
        return {int(lane): c for c, lane in enumerate(self.scenario.traffic_lights.lane_ids)}

    def _stopped(self, lane_id: int) -> np.ndarray | None:
        """[T]: map lane `lane_id` leads only into signalled links (its own and its successors' signals) none of
        which shows go; None when none of them is signalled."""
        return self._cached("stopped", lane_id, self._stopped_of)

    def _stopped_of(self, lane_id: int) -> np.ndarray | None:
        lane, column, go = self.scenario.road_map.by_id[lane_id], self._columns, self._go
        cols = [column[n] for n in (lane.id, *lane.exit_lanes) if n in column]
        return ~go[:, cols].any(axis=1) if cols and go is not None else None

    def _red_at(self, a: int, steps: np.ndarray) -> np.ndarray:
        """[S]: at `steps`, agent `a`'s lane leads only into signalled links none of which shows go (waiting at a
        red light is no yield), or a stop point with a non-go signal lies just ahead of its front (each step is
        decided from itself alone)."""
        out = np.zeros(len(steps), bool)
        go = self._go
        if go is None or not steps.size:
            return out
        lanes = self.lanes.lanes_at(a, steps)
        for lane in np.unique(lanes[lanes >= 0]).tolist():
            stopped = self._stopped(lane)
            if stopped is not None:
                out |= (lanes == lane) & stopped[steps]
        stops = self.scenario.traffic_lights.stop_points[:, :2]
        rel = stops[None, :, :] - self.xy[a, steps][:, None, :]  # [S, L, 2]
        cos, sin = np.cos(self.heading[a, steps])[:, None], np.sin(self.heading[a, steps])[:, None]
        along = rel[..., 0] * cos + rel[..., 1] * sin - 0.5 * self.length[a, steps][:, None]
        lateral = np.abs(rel[..., 1] * cos - rel[..., 0] * sin)
        near = (along > -1.0) & (along < self.config.red_distance) & (lateral < 2.0)
        return (out | (near & ~go[steps]).any(axis=-1)) & self.valid[a, steps]

    def _every_agent(self, row_of: Callable[[int], np.ndarray]) -> np.ndarray:
        """[A, T]: `row_of` each agent (every agent's lane matched at once first where signals need lanes)."""
        if self._go is not None:
            _ = self.lanes.per_step
        out = np.zeros(self.valid.shape, bool)
        for a in range(len(self.ids)):
            out[a] = row_of(a)
        return out

    @cached_property
    def red(self) -> np.ndarray:
        """[A, T]: `red_of` every agent."""
        return self._every_agent(self.red_of)

    def red_of(self, a: int) -> np.ndarray:
        """[T]: agent `a` waits at a red light (`_red_at` every step)."""
        return self._red_at(a, np.arange(self.num_steps))

    @cached_property
    def held(self) -> np.ndarray:
        """[A, T]: `held_of` every agent."""
        return self._every_agent(self.held_of)

    def held_of(self, a: int) -> np.ndarray:
        """[T]: agent `a` is slow (below `held_speed`) or braking (harder than `braking`), valid, and not waiting
        at a red light (`_red_at`, asked only at the slow steps)."""
        return self._cached("held", a, self._held_of)

    def _held_of(self, a: int) -> np.ndarray:
        cfg = self.config
        out = ((self.speed[a] < cfg.held_speed) | (self.accel[a] < cfg.braking)) & self.valid[a]
        slow = np.flatnonzero(out)
        out[slow] = ~self._red_at(a, slow)
        return out

    # ------------------------------------------------------------ yields at conflict points
    def _branches(self, a: int) -> list[tuple[np.ndarray, np.ndarray]]:
        """a's possible paths from its first valid step: its trajectory extended straight by `wait_extension`; for
        a vehicle standing all window (its way on is unknown), its lane and each chain of successor lanes instead
        (`LaneGeometry.continuations`, none on a signal-controlled approach); points [N, 2] and headings [N]."""
        return self._cached("branches", a, self._branches_of)

    def _branches_of(self, a: int) -> list[tuple[np.ndarray, np.ndarray]]:
        path = self.paths.waiting_path(a)
        assert path is not None
        real = path.points[path.real]
        last = np.flatnonzero(self.valid[a])[-1]
        continue_on = self.config.continue_on_map and self.arrays.is_static(a) and self.held_of(a)[last]
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
        path_b = self.paths.driven_path(b)
        assert path_b is not None
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
        mask = self.held_of(a) & self.valid[b] & (steps <= last_in) & (steps < reach_a)
        if not mask.any():
            return mask
        approaching = (dist_b / np.maximum(self.speed[b], 1.0) <= cfg.foe_horizon_s) & ~self.held_of(b)
        mask &= approaching | inside_b
        held = np.flatnonzero(mask)
        mask[held] = ~self._queued(a, point, held)
        return mask

    def _queued(self, a: int, point: np.ndarray, steps: np.ndarray) -> np.ndarray:
        """[S]: at `steps`, a's leader (on a's path) is between a and `point`, so a waits behind it, not for a
        foe."""
        lead = self.paths.leaders_at(a, steps)
        out = np.zeros(len(steps), bool)
        has = lead >= 0
        if not has.any():
            return out
        at = steps[has]
        to_point = np.linalg.norm(point - self.xy[a, at], axis=1)
        to_lead = np.linalg.norm(self.xy[lead[has], at] - self.xy[a, at], axis=1)
        out[has] = to_lead < to_point
        return out

    def _box(self, a: int) -> tuple[np.ndarray, np.ndarray] | None:
        """The box of mover a's path from its first step on (its trajectory and straight extension), grown by the
        wait extension and the conflict radius; None for an agent without a path."""
        return self._cached("box", a, self._box_of)

    def _box_of(self, a: int) -> tuple[np.ndarray, np.ndarray] | None:
        path = self.paths.driven_path(a)
        if path is None:
            return None
        real = path.points[path.arc >= 0.0]
        grow = self.config.wait_extension + self.config.conflict_radius
        return real.min(axis=0) - grow, real.max(axis=0) + grow

    def _candidate(self, a: int, b: int) -> bool:
        """Whether movers a and b (distinct) have paths whose boxes (`_box`) overlap."""
        box_a, box_b = self._box(a), self._box(b)
        if a == b or box_a is None or box_b is None:
            return False
        return bool((box_a[0] <= box_b[1]).all() and (box_b[0] <= box_a[1]).all())

    def pair_yields(self, a: int, b: int) -> list[Pair]:
        """The yield runs of vehicle or cyclist `a` waiting for vehicle or cyclist `b`: a is held (`held_of`)
        before the conflict point of one of its branches with b's path while b, reaching it first, is near it
        (`_yield_mask`), for `min_event_steps` (runs up to `merge_gap` apart joined). A parked car yields to no
        one, and no one yields to a car standing all window (it never goes first). Empty for any other pair, and
        where the two paths' boxes do not overlap. The one definition of a vehicle's yield: `vehicle_yields` is
        this over every pair."""
        return self._yields(a, b) if self._candidate(a, b) else []

    def _yields(self, a: int, b: int) -> list[Pair]:
        """`pair_yields` of movers a and b whose boxes overlap."""
        cfg = self.config
        if self.arrays.is_static(b) or not self.held_of(a).any() or self.arrays.is_parked(a):
            return []
        mask = np.zeros(self.num_steps, bool)
        for branch in self._branches(a):
            point = self._conflict_point(branch, b)
            found = None if point is None else self._yield_mask(a, b, point)
            if found is not None:
                mask |= found
        return [Pair(a, b, s, e) for s, e in true_runs(mask, cfg.min_event_steps, cfg.merge_gap)]

    @cached_property
    def vehicle_yields(self) -> list[Pair]:
        """`pair_yields` of every ordered pair of movers (A yields to B where their paths cross), the boxes of all
        movers compared at once."""
        keys = sorted(self.paths.driven)
        if not keys:
            return []
        boxes = [self._box(a) for a in keys]
        lo, hi = np.array([box[0] for box in boxes]), np.array([box[1] for box in boxes])  # type: ignore[index]
        overlap = (lo[:, None] <= hi[None, :]).all(axis=-1) & (lo[None, :] <= hi[:, None]).all(axis=-1)
        np.fill_diagonal(overlap, False)
        return [p for i, j in zip(*np.nonzero(overlap), strict=True) for p in self._yields(keys[i], keys[j])]
