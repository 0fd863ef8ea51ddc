"""Agents' paths, path leaders and following runs for the interaction detector (docs/interdrive.md,
'Interaction labels').

A path is an agent's own trajectory over the window, resampled and extended straight at both ends; agent L leads
F at a step when L's centre lies on F's path (or straight ahead in F's heading frame), heading along it, and no
other mover is nearer on it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from langtraj.angles import wrap_angle
from langtraj.interdrive.detector.parts import Pair, ScenePart
from langtraj.runs import true_runs


@dataclass(frozen=True)
class Path:
    """An agent's path: resampled points [P, 2], tangent headings [P], arc lengths [P] and, per step, the arc
    length of the agent (NaN where invalid); `real` marks points within the observed trajectory."""

    points: np.ndarray
    heading: np.ndarray
    arc: np.ndarray
    step_arc: np.ndarray
    real: np.ndarray


def project(path: Path, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Arc length, lateral offset and path heading at the projection of `points` [N, 2] onto `path`."""
    d = np.linalg.norm(points[:, None, :] - path.points[None, :, :], axis=-1)
    k = np.argmin(d, axis=1)
    tangent = np.stack([np.cos(path.heading[k]), np.sin(path.heading[k])], axis=1)
    rel = points - path.points[k]
    along = np.einsum("nd,nd->n", rel, tangent)
    lateral = np.abs(rel[:, 0] * tangent[:, 1] - rel[:, 1] * tangent[:, 0])
    return path.arc[k] + along, lateral, path.heading[k]


class PathGeometry(ScenePart):
    """Paths of the movers, their leaders per step and the following runs."""

    def path(self, a: int, back: float, ahead: float) -> Path | None:
        """Agent `a`'s trajectory extended `back` m before its first valid step and `ahead` m past its last."""
        steps = np.flatnonzero(self.valid[a])
        if steps.size == 0:
            return None
        pts = self.xy[a, steps]
        seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        arc = np.concatenate([[0.0], np.cumsum(seg)])
        h0, h1 = self.heading[a, steps[0]], self.heading[a, steps[-1]]
        start = pts[0] - back * np.array([math.cos(h0), math.sin(h0)])
        end = pts[-1] + ahead * np.array([math.cos(h1), math.sin(h1)])
        pts = np.concatenate([start[None], pts, end[None]])
        arc = np.concatenate([[-back], arc, [arc[-1] + ahead]])
        keep = np.concatenate([[True], np.diff(arc) > 1e-6])
        pts, arc = pts[keep], arc[keep]
        sample = np.arange(-back, arc[-1] + 1e-9, self.config.path_spacing)
        points = np.stack([np.interp(sample, arc, pts[:, 0]), np.interp(sample, arc, pts[:, 1])], axis=1)
        diff = np.gradient(points, axis=0) if len(points) > 1 else np.array([[math.cos(h0), math.sin(h0)]])
        step_arc = np.full(self.num_steps, np.nan)
        step_arc[steps] = np.concatenate([[0.0], np.cumsum(seg)])
        real = (sample >= 0.0) & (sample <= arc[-2] + 1e-9)
        return Path(points, np.arctan2(diff[:, 1], diff[:, 0]), sample, step_arc, real)

    @cached_property
    def _per_agent(self) -> dict[tuple[str, int], object]:
        """Per-agent paths and leader rows computed so far."""
        return {}

    def driven_path(self, a: int) -> Path | None:
        """The path of vehicle or cyclist `a` (20 m back, `path_extension` ahead); None for other agents and one
        never valid."""
        key = ("driven", a)
        if key not in self._per_agent:
            self._per_agent[key] = self.path(a, 20.0, self.config.path_extension) if self.movers[a] else None
        return self._per_agent[key]  # type: ignore[return-value]

    def waiting_path(self, a: int) -> Path | None:
        """The path of mover `a` as a yielding vehicle's: from its first step, `wait_extension` ahead (None where
        `driven_path` is)."""
        key = ("waiting", a)
        if key not in self._per_agent:
            keep = self.driven_path(a) is not None
            self._per_agent[key] = self.path(a, 0.0, self.config.wait_extension) if keep else None
        return self._per_agent[key]  # type: ignore[return-value]

    @cached_property
    def driven(self) -> dict[int, Path]:
        """`driven_path` of every vehicle and cyclist that has one."""
        return {a: p for a in np.flatnonzero(self.movers).tolist() if (p := self.driven_path(a)) is not None}

    @cached_property
    def waiting(self) -> dict[int, Path]:
        """`waiting_path` of every mover in `driven`."""
        return {a: p for a in self.driven if (p := self.waiting_path(a)) is not None}

    @cached_property
    def leaders(self) -> np.ndarray:
        """Leader agent index of each agent per step [A, T] (-1 when none): `leaders_of` every agent."""
        out = np.full(self.valid.shape, -1, np.int64)
        for f in self.driven:
            out[f] = self.leaders_of(f)
        return out

    def leaders_of(self, f: int) -> np.ndarray:
        """Leader agent index of agent `f` per step [T] (-1 when none): the nearest other mover on f's path (or
        straight ahead in f's heading frame), heading along it (see the module)."""
        key = ("leaders", f)
        if key not in self._per_agent:
            self._per_agent[key] = self._leaders_at(f, np.arange(self.num_steps))
        return self._per_agent[key]  # type: ignore[return-value]

    def leaders_at(self, f: int, steps: np.ndarray) -> np.ndarray:
        """`leaders_of` agent `f` at `steps` [S] (each step's leader is found from that step alone)."""
        key = ("leaders", f)
        if key in self._per_agent:
            return self._per_agent[key][steps]  # type: ignore[index]
        return self._leaders_at(f, steps)

    def _ahead(
        self, f: int, others: np.ndarray, steps: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Where `others` [O] stand relative to agent f at `steps` [S]: offsets [O, S, 2], f's heading cos and sin
        [1, S], distance along f's heading [O, S], and [O, S] whether each may lead f there (both valid, ahead of
        f, within `leader_search`)."""
        rel = self.xy[np.ix_(others, steps)] - self.xy[f, steps][None]
        cos, sin = np.cos(self.heading[f, steps])[None], np.sin(self.heading[f, steps])[None]
        along = rel[..., 0] * cos + rel[..., 1] * sin
        near = self.valid[np.ix_(others, steps)] & self.valid[f, steps][None, :]
        near &= (along > 0.0) & (np.linalg.norm(rel, axis=-1) < self.config.leader_search)
        return rel, cos, sin, along, near

    def _leaders_at(self, f: int, steps: np.ndarray, among: np.ndarray | None = None) -> np.ndarray:
        """`leaders_at`, the leader chosen among agents `among` (every other mover by default)."""
        cfg = self.config
        out = np.full(len(steps), -1, np.int64)
        path = self.driven_path(f)
        movers = np.flatnonzero(self.movers) if among is None else among
        others = movers[movers != f]
        if path is None or others.size == 0 or steps.size == 0:
            return out
        rel, cos, sin, along, near = self._ahead(f, others, steps)
        li, si = np.nonzero(near)
        if li.size == 0:
            return out
        lead, ti = others[li], steps[si]  # si indexes `steps`, ti the scene's steps
        half = 0.5 * (self.length[lead, ti] + self.length[f, ti])
        arc, lateral, heading = project(path, self.xy[lead, ti])
        on_path = (lateral < cfg.leader_lateral) & (arc - path.step_arc[ti] > 0.5)
        same_heading = np.abs(wrap_angle(self.heading[lead, ti] - heading)) < cfg.leader_heading
        gap = arc - path.step_arc[ti] - half
        # straight ahead in the follower's own lane too (its path bends away before a lane change)
        side = np.abs(rel[li, si, 1] * cos[0, si] - rel[li, si, 0] * sin[0, si])
        ahead = (side < cfg.leader_lateral) & (along[li, si] - half < cfg.straight_range)
        ahead &= np.abs(wrap_angle(self.heading[lead, ti] - self.heading[f, ti])) < cfg.leader_heading
        gap = np.where(on_path & same_heading, gap, along[li, si] - half)
        ok = ((on_path & same_heading) | ahead) & (gap > -1.0) & (gap < cfg.leader_range)
        if not ok.any():
            return out
        lead, si, gap = lead[ok], si[ok], gap[ok]
        order = np.lexsort((gap, si))
        first = np.concatenate([[True], np.diff(si[order]) != 0])
        out[si[order][first]] = lead[order][first]
        return out

    @cached_property
    def follows(self) -> list[Pair]:
        """`following` runs of every agent behind each of its leaders."""
        pairs = []
        for f in range(len(self.ids)):
            leaders = self.leaders_of(f)
            for lead in np.unique(leaders[leaders >= 0]).tolist():
                pairs.extend(self.following(f, lead))
        return pairs

    def following(self, f: int, lead: int) -> list[Pair]:
        """Runs of at least `min_follow_steps` of agent `f` behind leader `lead` (flickers up to
        `follow_merge_gap` joined). A parked follower follows no one, nor does a static one behind a parked
        leader (cars parked in a row); a static follower is kept behind a leader that is not parked (queued at a
        junction). The leaders of f are looked up only at the steps where lead alone would lead it."""
        cfg = self.config
        if self.arrays.is_parked(f) or (self.arrays.is_static(f) and self.arrays.is_parked(lead)):
            return []
        steps = np.arange(self.num_steps)
        if ("leaders", f) not in self._per_agent:  # only where lead alone would lead f
            steps = steps[self._leaders_at(f, steps, np.array([lead])) == lead]
        behind = np.zeros(self.num_steps, bool)
        behind[steps] = self.leaders_at(f, steps) == lead
        runs = true_runs(behind, max_gap=cfg.follow_merge_gap)
        return [Pair(f, lead, a, b) for a, b in runs if b - a >= cfg.min_follow_steps]
