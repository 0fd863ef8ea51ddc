"""Pedestrians and crosswalks for the interaction detector (docs/interdrive.md, 'Interaction labels'): held
vehicles yielding to a pedestrian on a crosswalk ahead, and pedestrians waiting at a crosswalk for vehicles.
"""

from __future__ import annotations

from functools import cached_property

import numpy as np
from matplotlib.path import Path as MplPath

from langtraj.interdrive.detector.arrays import SceneArrays
from langtraj.interdrive.detector.parts import Pair, ScenePart
from langtraj.interdrive.detector.yields import YieldGeometry
from langtraj.runs import true_runs
from langtraj.scenario.types import AgentType, MapFeatureType


class CrosswalkGeometry(ScenePart):
    """Crosswalk polygons, pedestrians on them, and the yields and waits around them (held vehicles from
    `yields`)."""

    def __init__(self, arrays: SceneArrays, yields: YieldGeometry):
        super().__init__(arrays)
        self.yields = yields

    @cached_property
    def crosswalks(self) -> list[MplPath]:
        return [
            MplPath(f.points[:, :2])
            for f in self.scenario.road_map.of_type(MapFeatureType.CROSSWALK)
            if len(f.points) >= 3
        ]

    @cached_property
    def _peds(self) -> np.ndarray:
        return np.flatnonzero(self.types == AgentType.PEDESTRIAN)

    @cached_property
    def ped_on_crosswalk(self) -> np.ndarray:
        """[C, A, T]: the pedestrian's centre is inside crosswalk c."""
        out = np.zeros((len(self.crosswalks), *self.valid.shape), bool)
        peds = self._peds
        if not peds.size:
            return out
        pts = self.xy[peds].reshape(-1, 2)
        for c, cw in enumerate(self.crosswalks):
            out[c, peds] = cw.contains_points(pts).reshape(len(peds), -1) & self.valid[peds]
        return out

    @cached_property
    def _per_agent(self) -> dict[tuple[str, int], object]:
        """Per-agent crosswalk hits and waits computed so far."""
        return {}

    def _hits(self, v: int) -> dict[int, list[int]]:
        """Per pedestrian p: the steps at which held vehicle or cyclist `v`'s look-ahead runs over a crosswalk on
        which p is the nearest pedestrian to it."""
        key = ("hits", v)
        if key not in self._per_agent:
            self._per_agent[key] = self._hits_of(v)
        return self._per_agent[key]  # type: ignore[return-value]

    def _hits_of(self, v: int) -> dict[int, list[int]]:
        cfg = self.config
        hits: dict[int, list[int]] = {}
        if not self.movers[v]:
            return hits
        held = self.yields.held_of(v)
        ahead = np.linspace(0.5, cfg.ped_lookahead, 24)
        for c, cw in enumerate(self.crosswalks):
            occupied = self.ped_on_crosswalk[c].any(axis=0)
            if not occupied.any():
                continue
            steps = np.flatnonzero(held & occupied)
            if steps.size == 0:
                continue
            reach = 0.5 * self.length[v, steps][:, None] + ahead[None, :]
            direction = np.stack([np.cos(self.heading[v, steps]), np.sin(self.heading[v, steps])], axis=-1)
            probes = self.xy[v, steps][:, None, :] + reach[..., None] * direction[:, None, :]
            over = cw.contains_points(probes.reshape(-1, 2)).reshape(len(steps), -1).any(axis=1)
            for t in steps[over].tolist():
                peds = np.flatnonzero(self.ped_on_crosswalk[c, :, t])
                p = int(peds[np.argmin(np.linalg.norm(self.xy[peds, t] - self.xy[v, t], axis=1))])
                hits.setdefault(p, []).append(t)
        return hits

    def pedestrian_yield_runs(self, v: int, p: int) -> list[Pair]:
        """Vehicle or cyclist `v` yields to pedestrian `p`: v is held while its look-ahead `ped_lookahead` m ahead
        of its front runs over a crosswalk on which p is the nearest walking pedestrian, for `min_event_steps`
        (runs up to `merge_gap` apart joined). The one definition: `pedestrian_yields` is this over every pair."""
        cfg = self.config
        steps = self._hits(v).get(p)
        if not steps:
            return []
        mask = np.zeros(self.num_steps, bool)
        mask[steps] = True
        return [Pair(v, p, s, e) for s, e in true_runs(mask, cfg.min_event_steps, cfg.merge_gap)]

    @cached_property
    def pedestrian_yields(self) -> list[Pair]:
        """Held vehicles whose look-ahead runs over a crosswalk with a pedestrian on it, to the nearest one
        (`pedestrian_yield_runs` of every pair)."""
        return [
            pair
            for v in np.flatnonzero(self.movers).tolist()
            for p in sorted(self._hits(v))
            for pair in self.pedestrian_yield_runs(v, p)
        ]

    def _on_crosswalk(self, c: int, v: int, start: int, end: int) -> np.ndarray:
        xy = self.xy[v, start:end]
        cw = self.crosswalks[c]
        m = self.config.crosswalk_margin
        inside = cw.contains_points(xy, radius=m) | cw.contains_points(xy, radius=-m)
        return start + np.flatnonzero(inside & self.valid[v, start:end])

    def _crosswalk_near(self, point: np.ndarray) -> np.ndarray:
        """[C]: the one crosswalk nearest to `point` within `crosswalk_search` (none when none is)."""
        out = np.zeros(len(self.crosswalks), bool)
        best, best_d = -1, self.config.crosswalk_search
        for c, cw in enumerate(self.crosswalks):
            d = 0.0 if cw.contains_point(point) else float(np.min(np.linalg.norm(cw.vertices - point, axis=1)))
            if d < best_d:
                best, best_d = c, d
        if best >= 0:
            out[best] = True
        return out

    def _waits(self, p: int) -> list[tuple[int, int, int]]:
        """(start, end, crosswalk) of each wait of pedestrian `p`: standing (not on a crosswalk) for at least
        `min_event_steps` next to a crosswalk it steps onto within `wait_to_cross_steps` after (or, standing to the
        window's end, the crosswalk within `crosswalk_search`)."""
        key = ("waits", p)
        if key not in self._per_agent:
            self._per_agent[key] = self._waits_of(p)
        return self._per_agent[key]  # type: ignore[return-value]

    def _waits_of(self, p: int) -> list[tuple[int, int, int]]:
        cfg = self.config
        out: list[tuple[int, int, int]] = []
        if self.types[p] != AgentType.PEDESTRIAN or not self.crosswalks:
            return out
        on_any = self.ped_on_crosswalk[:, p].any(axis=0)
        standing = self.valid[p] & (self.speed[p] <= cfg.stopped_speed) & ~on_any
        for w0, w1 in true_runs(standing):
            if w1 - w0 < cfg.min_event_steps:
                continue
            later = self.ped_on_crosswalk[:, p, w1 : w1 + cfg.wait_to_cross_steps].any(axis=1)
            if w1 >= self.num_steps and not later.any():
                later = self._crosswalk_near(self.xy[p, w1 - 1])
            out.extend((w0, w1, c) for c in np.flatnonzero(later).tolist())
        return out

    def _wait_pair(self, p: int, v: int, wait: tuple[int, int, int]) -> tuple[Pair, Pair] | None:
        """(P yields to V over `wait`, V passes P over its steps on the crosswalk), or None when v is not on the
        wait's crosswalk during it."""
        w0, w1, c = wait
        steps = self._on_crosswalk(c, v, w0, w1)
        return (Pair(p, v, w0, w1), Pair(v, p, int(steps[0]), int(steps[-1]) + 1)) if steps.size else None

    def pedestrian_wait_runs(self, p: int, v: int) -> list[tuple[Pair, Pair]]:
        """(P yields to V over its wait, V passes P over its steps on the crosswalk) for each wait of pedestrian
        `p` (`_waits`) during which vehicle or cyclist `v` is on that crosswalk. The one definition:
        `pedestrian_waits` is this over every pair."""
        if not self.movers[v]:
            return []
        return [pair for wait in self._waits(p) if (pair := self._wait_pair(p, v, wait)) is not None]

    @cached_property
    def pedestrian_waits(self) -> list[tuple[Pair, Pair]]:
        """(P yields to V over its wait, V passes P over its steps on the crosswalk) for pedestrians standing
        next to a crosswalk they then step onto, for each vehicle on that crosswalk during the wait
        (`pedestrian_wait_runs` of every pair, by pedestrian, wait, then vehicle)."""
        movers = np.flatnonzero(self.movers).tolist()
        return [
            pair
            for p in self._peds.tolist()
            for wait in self._waits(p)
            for v in movers
            if (pair := self._wait_pair(p, v, wait)) is not None
        ]
