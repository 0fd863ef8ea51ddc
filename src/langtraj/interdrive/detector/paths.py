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
    def driven(self) -> dict[int, Path]:
        """The path of every vehicle and cyclist (20 m back, `path_extension` ahead)."""
        out = {}
        for a in np.flatnonzero(self.movers).tolist():
            path = self.path(a, 20.0, self.config.path_extension)
            if path is not None:
                out[a] = path
        return out

    @cached_property
    def waiting(self) -> dict[int, Path]:
        """The path of every mover as a yielding vehicle's: from its first step, `wait_extension` ahead."""
        return {a: p for a in self.driven if (p := self.path(a, 0.0, self.config.wait_extension)) is not None}

    @cached_property
    def leaders(self) -> np.ndarray:
        """Leader agent index of each agent per step [A, T] (-1 when none)."""
        cfg = self.config
        out = np.full(self.valid.shape, -1, np.int64)
        movers = np.flatnonzero(self.movers)
        for f, path in self.driven.items():
            others = movers[movers != f]
            if others.size == 0:
                continue
            near = self.valid[others] & self.valid[f][None, :]
            rel = self.xy[others] - self.xy[f][None]
            cos, sin = np.cos(self.heading[f])[None], np.sin(self.heading[f])[None]
            along = rel[..., 0] * cos + rel[..., 1] * sin
            li, ti = np.nonzero(near & (along > 0.0) & (np.linalg.norm(rel, axis=-1) < cfg.leader_search))
            if li.size == 0:
                continue
            lead = others[li]
            half = 0.5 * (self.length[lead, ti] + self.length[f, ti])
            arc, lateral, heading = project(path, self.xy[lead, ti])
            on_path = (lateral < cfg.leader_lateral) & (arc - path.step_arc[ti] > 0.5)
            same_heading = np.abs(wrap_angle(self.heading[lead, ti] - heading)) < cfg.leader_heading
            gap = arc - path.step_arc[ti] - half
            # straight ahead in the follower's own lane too (its path bends away before a lane change)
            side = np.abs(rel[li, ti, 1] * cos[0, ti] - rel[li, ti, 0] * sin[0, ti])
            ahead = (side < cfg.leader_lateral) & (along[li, ti] - half < cfg.straight_range)
            ahead &= np.abs(wrap_angle(self.heading[lead, ti] - self.heading[f, ti])) < cfg.leader_heading
            gap = np.where(on_path & same_heading, gap, along[li, ti] - half)
            ok = ((on_path & same_heading) | ahead) & (gap > -1.0) & (gap < cfg.leader_range)
            if not ok.any():
                continue
            lead, ti, gap = lead[ok], ti[ok], gap[ok]
            order = np.lexsort((gap, ti))
            first = np.concatenate([[True], np.diff(ti[order]) != 0])
            out[f, ti[order][first]] = lead[order][first]
        return out

    @cached_property
    def follows(self) -> list[Pair]:
        """Runs of at least `min_follow_steps` behind one leader. A parked follower follows no one, nor does a
        static one behind a static leader (cars parked in a row); a static follower is kept behind a leader that
        moves in the window (queued at a junction)."""
        cfg = self.config
        pairs = []
        for f in range(len(self.ids)):
            if self.parked[f]:
                continue
            leaders = self.leaders[f]
            for lead in np.unique(leaders[leaders >= 0]).tolist():
                if self.static[f] and self.parked[lead]:
                    continue
                for a, b in true_runs(leaders == lead, max_gap=cfg.follow_merge_gap):
                    if b - a >= cfg.min_follow_steps:
                        pairs.append(Pair(f, lead, a, b))
        return pairs
