"""Map lanes for the interaction detector (docs/interdrive.md, 'Interaction labels'): each mover's lane per step,
lane leaders along a lane and its successors, the map lanes a standing car may drive on, and roundabout rings.

Lanes are named by map feature id here (the rules look features up in `RoadMap.by_id`); matching itself is
`MapIndex.match_lanes`.
"""

from __future__ import annotations

import math
from functools import cached_property

import numpy as np

from langtraj.angles import wrap_angle
from langtraj.interdrive.detector.arrays import SceneArrays
from langtraj.interdrive.detector.parts import ScenePart
from langtraj.interdrive.detector.paths import PathGeometry


class LaneGeometry(ScenePart):
    """Lane matches, lane leaders, lane continuations and roundabouts of one scene; `paths` gives the path leader
    where the map has no lane."""

    def __init__(self, arrays: SceneArrays, paths: PathGeometry):
        super().__init__(arrays)
        self.paths = paths

    @cached_property
    def polylines(self) -> dict[int, tuple[np.ndarray, np.ndarray]]:
        """Every lane (junction lanes included): points [N, 2] and tangent headings [N]."""
        out = {}
        for lane in self.scenario.road_map.lanes:
            if len(lane.points) >= 2:
                p = lane.points[:, :2]
                d = np.gradient(p, axis=0)
                out[lane.id] = (p, np.arctan2(d[:, 1], d[:, 0]))
        return out

    def lane_ids(self, xy: np.ndarray, heading: np.ndarray, exclude_junctions: bool) -> np.ndarray:
        """Map lane id of each point's lane match (`SceneArrays.match_lanes`; -1 where none)."""
        match = self.arrays.match_lanes(xy, heading, exclude_junctions)
        return np.where(match.matched, self.map_index.lane_ids[np.maximum(match.lane, 0)], -1)

    @cached_property
    def per_step(self) -> np.ndarray:
        """Map lane id (junction lanes left out) of each vehicle and cyclist per step [A, T] (-1 when none)."""
        out = np.full(self.valid.shape, -1, np.int64)
        mask = self.valid & self.movers[:, None]
        if self.map_index.has_lanes and mask.any():
            out[mask] = self.lane_ids(self.xy[mask], self.heading[mask], exclude_junctions=True)
        return out

    def lanes_at(self, a: int, steps: np.ndarray) -> np.ndarray:
        """Map lane id of agent `a` at `steps` [S], as in `per_step` (a lane match is per point): matched at those
        steps alone unless `per_step` is already computed."""
        if "per_step" in self.__dict__:
            return self.per_step[a, steps]
        out = np.full(len(steps), -1, np.int64)
        keep = self.valid[a, steps] & self.movers[a]
        if self.map_index.has_lanes and keep.any():
            at = steps[keep]
            out[keep] = self.lane_ids(self.xy[a, at], self.heading[a, at], exclude_junctions=True)
        return out

    @cached_property
    def has_connectivity(self) -> bool:
        """Whether some lane of the map names a successor or a predecessor."""
        # Unlike `MapIndex.has_connectivity`, a link to a lane outside the (cropped) map counts: it shows the map
        # has links, so a lane without successors does end (see `LaneChangeGeometry.is_merge`).
        return any(lane.exit_lanes or lane.entry_lanes for lane in self.scenario.road_map.lanes)

    @cached_property
    def has_roundabout(self) -> bool:
        """Whether the map holds a ring: a chain of successor lanes shorter than `ring_length` back to its start
        that turns by a full circle one way, every lane of it (but those shorter than `ring_short_lane`) curving
        that way by at least `ring_min_curvature` (a loop of straight roads and turns around a block is none)."""
        cfg = self.config
        polylines = self.polylines
        by_id = self.scenario.road_map.by_id
        turn = {}
        length = {}
        for lid, (pts, heads) in polylines.items():
            turn[lid] = float(np.sum(wrap_angle(np.diff(heads)))) if len(heads) > 1 else 0.0
            length[lid] = float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())

        def curving(lid: int, sign: float) -> bool:
            return length[lid] < cfg.ring_short_lane or sign * turn[lid] >= cfg.ring_min_curvature * length[lid]

        for start in polylines:
            sign = math.copysign(1.0, turn[start])
            if length[start] < cfg.ring_short_lane or not curving(start, sign):
                continue
            stack: list[tuple[int, float, float, tuple[int, ...]]] = [(start, 0.0, 0.0, (start,))]
            seen = {start}
            while stack:
                lid, total, angle, chain = stack.pop()
                total, angle = total + length[lid], angle + turn[lid]
                if total > cfg.ring_length:
                    continue
                for n in by_id[lid].exit_lanes:
                    if n == start and abs(angle) > 1.5 * math.pi and self._round(chain):
                        return True
                    if n in polylines and n not in seen and curving(n, sign):
                        seen.add(n)
                        stack.append((n, total, angle, (*chain, n)))
        return False

    def _round(self, chain: tuple[int, ...]) -> bool:
        """Whether the ring of lanes `chain` is about a circle: its points' least distance from their centroid is at
        least `ring_min_roundness` of the largest (a rounded rectangle around a block or a parking aisle is not)."""
        pts = np.concatenate([self.polylines[i][0] for i in chain])
        radius = np.linalg.norm(pts - pts.mean(axis=0), axis=1)
        return float(radius.min()) >= self.config.ring_min_roundness * float(radius.max())

    def chain(self, lane_id: int, a: int, t: int) -> set[int]:
        """`lane_id` and its successors (junction lanes included) up to `target_lane_range` ahead of agent `a` at
        step `t`; at a split only the branches a's later trajectory runs along (all when it runs along none)."""
        polylines = self.polylines
        by_id = self.scenario.road_map.by_id
        later = self.xy[a, t:][self.valid[a, t:]]
        seen = {lane_id}
        stack: list[tuple[int, float, np.ndarray | None]] = [(lane_id, 0.0, self.xy[a, t])]
        while stack:
            lid, length, start = stack.pop()
            if lid not in polylines:
                continue
            pts = polylines[lid][0]
            k = int(np.argmin(np.linalg.norm(pts - start, axis=1))) if start is not None else 0
            length += float(np.linalg.norm(np.diff(pts[k:], axis=0), axis=1).sum())
            if length >= self.config.target_lane_range:
                continue
            nexts = [n for n in by_id[lid].exit_lanes if n not in seen and n in polylines]
            if len(nexts) > 1 and len(later):
                driven = [n for n in nexts if _near(polylines[n][0], later, self.config.target_lane_lateral)]
                nexts = driven or nexts
            for n in nexts:
                seen.add(n)
                stack.append((n, length, None))
        return seen

    def leader(self, a: int, t: int, lane_id: int) -> int:
        """The nearest vehicle or cyclist ahead of agent `a` at step `t` whose centre lies on lane `lane_id` or
        its successors along a's way (heading along them); a's leader on its own path where the map has no such
        lane."""
        if lane_id < 0 or lane_id not in self.polylines:
            return int(self.paths.leaders[a, t])
        cfg = self.config
        others = np.flatnonzero(self.movers & self.valid[:, t])
        others = others[others != a]
        if not others.size or not self.valid[a, t]:
            return -1
        rel = self.xy[others, t] - self.xy[a, t]
        head = self.heading[a, t]
        along = rel[:, 0] * math.cos(head) + rel[:, 1] * math.sin(head)
        dist = np.linalg.norm(rel, axis=1)
        half = 0.5 * (self.length[others, t] + self.length[a, t])
        keep = (along - half > -0.5) & (dist < cfg.target_lane_range)
        others, dist = others[keep], dist[keep]
        if not others.size:
            return -1
        polylines = self.polylines
        chain = [polylines[i] for i in self.chain(lane_id, a, t)]
        pts = np.concatenate([c[0] for c in chain])
        heads = np.concatenate([c[1] for c in chain])
        d = np.linalg.norm(self.xy[others, t][:, None, :] - pts[None], axis=-1)
        aligned = np.abs(wrap_angle(heads[None, :] - self.heading[others, t][:, None])) < cfg.lane_match_heading
        on = np.where(aligned, d, np.inf).min(axis=1) < cfg.target_lane_lateral
        if not on.any():
            return -1
        return int(others[on][np.argmin(dist[on])])

    def continuations(self, a: int) -> list[np.ndarray]:
        """Map polylines [N, 2] an agent may drive on after its last valid step: the rest of its lane, then each
        chain of successor lanes up to `continuation_length` (empty when no lane matches, and when the way runs
        over a lane with a traffic light: there the light gives the right of way, see `YieldGeometry.red`)."""
        cfg = self.config
        steps = np.flatnonzero(self.valid[a])
        if steps.size == 0 or not self.polylines:
            return []
        here, head = self.xy[a, steps[-1]], self.heading[a, steps[-1]]
        best = int(self.lane_ids(here[None], np.array([head]), exclude_junctions=False)[0])
        if best < 0 or best not in self.polylines:
            return []
        best_k = int(np.argmin(np.linalg.norm(self.polylines[best][0] - here, axis=1)))
        by_id = self.scenario.road_map.by_id
        signalled = {int(n) for n in self.scenario.traffic_lights.lane_ids}
        out = []
        stack = [(self.polylines[best][0][best_k:], by_id[best])]
        while stack:
            pts, lane = stack.pop()
            length = float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum()) if len(pts) > 1 else 0.0
            nexts = [n for n in lane.exit_lanes if n in self.polylines]
            if signalled & {lane.id, *nexts}:
                return []  # a signal-controlled approach: the light gives the right of way (see `red`)
            if length >= cfg.continuation_length or not nexts or len(out) + len(stack) > 16:
                out.append(pts)
                continue
            for n in nexts:
                stack.append((np.concatenate([pts, self.polylines[n][0]]), by_id[n]))
        return out


def _near(points: np.ndarray, track: np.ndarray, radius: float) -> bool:
    """Whether some point of `track` lies within `radius` of `points`' polyline points."""
    step = max(len(points) // 16, 1)
    d = np.linalg.norm(points[::step, None, :] - track[None, :, :], axis=-1)
    return bool((d < radius + 0.5 * step).any())
