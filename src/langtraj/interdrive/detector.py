"""A rule-based interaction detector from trajectories and map alone (no simulator events).

For real scenes (Waymo, nuScenes) and to pre-fill the labeling tool. One `InteractionRule` per interaction type,
registered in `RULES`; `detect_interactions` runs them all over one shared, lazily computed `SceneGeometry`.
The rules mirror how `ground_truth.py` defines each type from SUMO's events, so the two can be compared with
`evaluation.match_interactions`:

- leader (shared): agent L is F's leader at step t when L's centre lies on F's path (F's own trajectory over
  the window, extended straight at both ends) within `leader_lateral` of it, heading along it, ahead of F by a
  bumper gap of at most `leader_range` (60 m, the range of SUMO's `follow` events), and no other vehicle or
  cyclist is nearer on that path.
- lane leader (shared): the leader of agent A on map lane X at step t is the nearest vehicle or cyclist ahead of A
  (within `target_lane_range`) whose centre lies within `target_lane_lateral` of X or of X's successors along A's
  way (junction lanes included; at a split only the branches A's later trajectory runs along), heading along them.
- standing agents: an agent whose valid positions over the whole window (history included) span at most
  `static_displacement` is static; a static one on no map lane (road side, parking lot) is parked.
- following: runs of at least `min_follow_steps` with the same leader (flickers up to `follow_merge_gap` joined).
  A parked follower follows no one, and a static follower no parked leader (cars parked in a row); a static
  follower on a lane behind a leader on a lane is a queue (at a red light or a junction) and is kept. Subtypes
  read only steps where both are valid.
- lane change: the agent's map lane (nearest non-junction lane centreline within `lane_match_distance`, heading
  within `lane_match_heading`) switches to a left/right neighbour lane (or, without neighbour data, to a
  parallel lane `lane_width_range` aside), confirmed as a manoeuvre (not a flicker of the nearest lane): the
  agent is not static, drives at a median `lane_change_min_speed` around the switch, and its signed offset from
  both the lane left and the lane entered changes by `lane_change_min_lateral` to `lane_change_max_lateral`
  within `lane_change_lateral_steps` of it; switches of one agent closer than `lane_change_half_span` are one
  manoeuvre. The other is the lane leader on the target lane right after the switch, or -1. Where the map has
  no lanes, `changing_lanes` agent labels stand in (the other is then the path leader). An overtaking lane change
  names the overtaken agent.
- merging: a lane change out of a lane that ends while the lane entered goes on: the lane left has no successors,
  and the target lane has some or runs on `lane_runs_on` past the lane left's end (a map crop cuts both alike);
  a map without lane connectivity (nuScenes) shows no lane ending, so it has no merges.
  On-ramp subtypes when no lane before the lane left lies beside (or is) a lane before the target lane.
- overtaking: a lane change of A whose former leader B (the lane leader on the lane left right before the switch)
  was slower, after which A gets ahead of B along B's heading within the window.
- yielding: (vehicles) the paths of A and B come within `conflict_radius` at a heading difference above
  `conflict_heading` (the conflict point); B reaches it first, and A is held (slower than `held_speed` or
  braking harder than `braking`, not in front of a red light, and not queued behind its own leader that is
  still before the conflict point) before it while B, not held itself, is at most `foe_horizon_s` from it, or
  is inside it, for `min_event_steps` (runs up to `merge_gap` apart joined); A's path is its trajectory extended
  straight by `wait_extension`, or, for an A standing all window (queued far back: its way on is unknown), its
  map lane and every chain of successor lanes when `continue_on_map` (off by default: on real scenes cars standing
  on lanes all window triple the yields; not over a signal-controlled lane, where the light decides, see `red`);
  a parked A yields to no one and
  no one yields to a B static all window. (pedestrians) A held vehicle whose
  look-ahead `ped_lookahead` m ahead of its front runs over a map crosswalk on which a pedestrian walks yields to
  the nearest such pedestrian. (pedestrian to vehicle) a pedestrian standing next to a crosswalk that it then
  steps onto (or, standing to the window's end, the crosswalk within `crosswalk_search`) yields to each vehicle
  that is on that crosswalk while it stands.
- passing: the reverse of every yield: B -> A at junctions (at roundabout when the map holds a round ring of
  curving lanes, see `SceneGeometry.has_roundabout`; `vru_crossing` for a cyclist B), pedestrian -> vehicle
  `vru_crossing`, vehicle -> waiting pedestrian `pedestrian`.

Only trajectories and the map are read (no simulator ids, events or window kind), so the rules run on real
scenes too. Single-agent labels are optional inputs: `changing_lanes` spans are used when the map has no lanes.
Labels are kept when they overlap [current_index, num_steps) by `min_window_s` (the ground truth's own window
filter) and are sorted as the ground truth's.
"""

from __future__ import annotations

import abc
import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import ClassVar

import numpy as np
from matplotlib.path import Path as MplPath

from langtraj.angles import wrap_angle
from langtraj.interdrive.ground_truth import filter_to_window, label_sort_key
from langtraj.interdrive.labels import AgentLabel, InteractionLabel, LabelSource
from langtraj.interdrive.mapindex import MapIndex
from langtraj.interdrive.taxonomy import SUBTYPES_BY_ID, InteractionType
from langtraj.registry import Registry
from langtraj.runs import true_runs
from langtraj.scenario.model import STEP_SECONDS, MapFeature, Scenario
from langtraj.scenario.types import AgentType, MapFeatureType, TrafficLightState


@dataclass(frozen=True)
class DetectorConfig:
    """Thresholds of the rules (m, m/s, m/s^2, radians, steps of 0.1 s)."""

    leader_range: float = 60.0  # m: largest bumper gap to a leader along the path
    leader_search: float = 70.0  # m: centre distance within which leaders are looked for
    leader_lateral: float = 1.5  # m: a leader's centre is at most this far from the follower's path
    straight_range: float = 30.0  # m: a leader straight ahead in the follower's heading frame counts up to this gap
    leader_heading: float = math.radians(45.0)  # a leader heads along the path within this
    path_spacing: float = 2.0  # m between resampled path points
    path_extension: float = 100.0  # m a path is extended straight past its last step (and 20 m before its first)
    min_follow_steps: int = 10  # steps a following run must last (1 s)
    follow_merge_gap: int = 2  # leader flickers up to this many steps are joined
    stopped_speed: float = 0.3  # m/s: at or below this an agent stands
    held_speed: float = 2.0  # m/s: below this a vehicle is held back
    braking: float = -0.5  # m/s^2: decelerating harder than this is held back
    foe_horizon_s: float = 4.0  # s: a foe counts while at most this far (in time) from the conflict point
    conflict_radius: float = 1.5  # m: two paths this close form a conflict point
    conflict_heading: float = math.radians(20.0)  # paths must cross at more than this angle
    wait_extension: float = 15.0  # m a yielding vehicle's path is extended past its last step (no map lane)
    continue_on_map: bool = False  # continue a vehicle standing all window along its map lane branches (opt-in)
    continuation_length: float = 60.0  # m of map lanes a path is continued by past its last step
    merge_gap: int = 5  # yield runs up to this many steps apart are joined
    min_event_steps: int = 5  # yield runs shorter than this are dropped
    red_distance: float = 12.0  # m: a stop point this far ahead of a vehicle's front with a non-go light holds it
    ped_lookahead: float = 12.0  # m ahead of a vehicle's front checked against crosswalks
    crosswalk_margin: float = 0.5  # m: a vehicle centre this close to a crosswalk is on it
    wait_to_cross_steps: int = 10  # a standing pedestrian must step onto the crosswalk within this many steps
    crosswalk_search: float = 5.0  # m: a pedestrian standing to the window's end waits at a crosswalk this near
    lane_match_distance: float = 2.0  # m: a lane centreline at most this far is the agent's lane
    lane_match_heading: float = math.radians(45.0)  # and heading along the agent within this
    lane_width_range: tuple[float, float] = (2.0, 5.0)  # m: offset of a parallel neighbour lane (no neighbour data)
    min_lane_steps: int = 3  # steps an agent must stay on a lane for the lane to count
    lane_change_half_span: int = 20  # steps a lane-change label reaches either side of the switch
    target_lane_range: float = 150.0  # m: a leader on the target lane of a lane change is looked for this far
    target_lane_lateral: float = 1.6  # m: a centre this close to a lane centreline is on that lane
    ring_length: float = 250.0  # m: a roundabout ring is at most this long
    ring_min_curvature: float = math.radians(0.5)  # rad/m: every ring lane turns the ring's way at least this much
    ring_min_roundness: float = 0.7  # a ring's least centroid distance is at least this share of its largest
    ring_short_lane: float = 2.0  # m: ring lanes shorter than this are exempt from `ring_min_curvature`
    static_displacement: float = 1.0  # m: an agent whose valid positions span at most this stands all window
    lane_change_min_speed: float = 2.0  # m/s: median speed within `lane_change_speed_steps` of a lane switch
    lane_change_speed_steps: int = 10  # steps either side of a switch over which its speed is taken
    lane_change_min_lateral: float = 1.5  # m: least sideways move across the target lane that confirms a switch
    lane_change_lateral_steps: int = 30  # steps either side of a switch between which the sideways move is taken
    lane_change_max_lateral: float = 8.0  # m: a larger sideways move is no change to a neighbour lane
    lane_runs_on: float = 5.0  # m: a target lane without successors must run on this far past the lane left
    overtake_lookback: int = 15  # steps before a switch at which the former leader is looked up
    high_speed: float = 20.0  # m/s: an overtake at or above this top speed is high-speed
    tailgating_headway_s: float = 0.6  # s: following with a time headway below this at speed is tailgating
    tailgating_speed: float = 5.0  # m/s
    slow_lead_ratio: float = 0.6  # a leader at most this share of the follower's earlier top speed is slow
    min_window_s: float = 1.0  # a label must overlap the current and future steps by this long


_MOVERS = (AgentType.VEHICLE, AgentType.CYCLIST)


def _signed_offset(line: np.ndarray, point: np.ndarray) -> float:
    """Signed distance (left positive) of `point` from polyline `line` [N, 2], the polyline extended straight past
    both ends."""
    if len(line) < 2:
        return 0.0
    a, b = line[:-1], line[1:]
    seg = b - a
    sq = np.maximum(np.einsum("nd,nd->n", seg, seg), 1e-12)
    t = np.einsum("nd,nd->n", point - a, seg) / sq
    lo = np.zeros(len(t))
    hi = np.ones(len(t))
    lo[0], hi[-1] = -np.inf, np.inf
    t = np.clip(t, lo, hi)
    proj = a + t[:, None] * seg
    k = int(np.argmin(np.linalg.norm(point - proj, axis=1)))
    rel = point - proj[k]
    side = seg[k, 0] * rel[1] - seg[k, 1] * rel[0]
    return float(math.copysign(np.linalg.norm(rel), side))


@dataclass(frozen=True)
class Path:
    """An agent's path: resampled points [P, 2], tangent headings [P], arc lengths [P] and, per step, the arc
    length of the agent (NaN where invalid); `real` marks points within the observed trajectory."""

    points: np.ndarray
    heading: np.ndarray
    arc: np.ndarray
    step_arc: np.ndarray
    real: np.ndarray


@dataclass(frozen=True)
class LaneChange:
    """A switch of agent `agent` (index) from lane `from_lane` to `to_lane` at step `switch`, over [start, end)."""

    agent: int
    switch: int
    start: int
    end: int
    from_lane: int
    to_lane: int


@dataclass(frozen=True)
class Pair:
    """Agent index `agent` does something to agent index `other` over [start, end)."""

    agent: int
    other: int
    start: int
    end: int


class SceneGeometry:
    """Per-scene quantities the rules share, each computed once on first use."""

    def __init__(
        self,
        scenario: Scenario,
        agent_labels: Sequence[AgentLabel],
        config: DetectorConfig,
        map_index: MapIndex | None = None,
    ):
        self.scenario = scenario
        self.agent_labels = tuple(agent_labels)
        self.config = config
        self.map_index = map_index or MapIndex.build(scenario.road_map)
        agents = scenario.agents
        self.xy = agents.xy.astype(np.float64)
        self.heading = agents.heading.astype(np.float64)
        self.speed = agents.speed.astype(np.float64)
        self.valid = agents.valid
        self.length = agents.states[..., 6].astype(np.float64)
        self.types = agents.types
        self.ids = agents.ids
        self.movers = np.isin(self.types, _MOVERS)
        steps = agents.num_steps
        self.accel = np.gradient(self.speed, STEP_SECONDS, axis=1) if steps > 1 else np.zeros_like(self.speed)

    # ------------------------------------------------------------ standing agents
    @cached_property
    def static(self) -> np.ndarray:
        """[A]: the agent stands over the whole window, history included: its valid positions span at most
        `static_displacement` (a parked car, or one waiting all window long)."""
        out = np.zeros(len(self.ids), bool)
        for a in range(len(self.ids)):
            pts = self.xy[a, self.valid[a]]
            if len(pts):
                out[a] = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0))) <= self.config.static_displacement
        return out

    @cached_property
    def parked(self) -> np.ndarray:
        """[A]: static and on no map lane at any step (the road side, a parking lot); every static agent where the
        map has no lanes."""
        if not self.scenario.road_map.lanes:
            return self.static.copy()
        out = self.static.copy()
        for a in np.flatnonzero(out).tolist():
            steps = self.valid[a]
            out[a] = not (self._match(self.xy[a, steps], self.heading[a, steps], exclude_junctions=False) >= 0).any()
        return out

    @property
    def num_steps(self) -> int:
        return self.scenario.num_steps

    # ------------------------------------------------------------ paths and leaders
    def _path(self, a: int, back: float, ahead: float) -> Path | None:
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
    def paths(self) -> dict[int, Path]:
        """The path of every vehicle and cyclist (20 m back, `path_extension` ahead)."""
        out = {}
        for a in np.flatnonzero(self.movers).tolist():
            path = self._path(a, 20.0, self.config.path_extension)
            if path is not None:
                out[a] = path
        return out

    def project(self, path: Path, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Arc length, lateral offset and path heading at the projection of `points` [N, 2] onto `path`."""
        d = np.linalg.norm(points[:, None, :] - path.points[None, :, :], axis=-1)
        k = np.argmin(d, axis=1)
        tangent = np.stack([np.cos(path.heading[k]), np.sin(path.heading[k])], axis=1)
        rel = points - path.points[k]
        along = np.einsum("nd,nd->n", rel, tangent)
        lateral = np.abs(rel[:, 0] * tangent[:, 1] - rel[:, 1] * tangent[:, 0])
        return path.arc[k] + along, lateral, path.heading[k]

    @cached_property
    def leaders(self) -> np.ndarray:
        """Leader agent index of each agent per step [A, T] (-1 when none)."""
        cfg = self.config
        out = np.full(self.valid.shape, -1, np.int64)
        movers = np.flatnonzero(self.movers)
        for f, path in self.paths.items():
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
            arc, lateral, heading = self.project(path, self.xy[lead, ti])
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

    # ------------------------------------------------------------ following
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

    # ------------------------------------------------------------ lanes and lane changes
    def _match(self, xy: np.ndarray, heading: np.ndarray, exclude_junctions: bool) -> np.ndarray:
        """Map lane id of each point (-1 where none): the nearest centreline within `lane_match_distance` among
        lanes heading within `lane_match_heading`."""
        cfg = self.config
        match = self.map_index.match_lanes(
            xy, heading, radius=cfg.lane_match_distance, max_heading_diff=cfg.lane_match_heading,
            heading_weight=0.0, drivable_only=False, exclude_junctions=exclude_junctions,
        )  # fmt: skip
        return np.where(match.matched, self.map_index.lane_ids[np.maximum(match.lane, 0)], -1)

    @cached_property
    def lanes(self) -> np.ndarray:
        """Map lane id (junction lanes left out) of each vehicle and cyclist per step [A, T] (-1 when none)."""
        out = np.full(self.valid.shape, -1, np.int64)
        mask = self.valid & self.movers[:, None]
        if self.map_index.has_lanes and mask.any():
            out[mask] = self._match(self.xy[mask], self.heading[mask], exclude_junctions=True)
        return out

    def _neighbours(self, a: MapFeature, b: MapFeature) -> bool:
        """Whether lanes a and b are side by side (neighbour data, else geometry)."""
        listed = {n.feature_id for n in (*a.left_neighbors, *a.right_neighbors)}
        listed |= {n.feature_id for n in (*b.left_neighbors, *b.right_neighbors)}
        if b.id in listed or a.id in listed:
            return True
        if a.left_neighbors or a.right_neighbors or b.left_neighbors or b.right_neighbors:
            return False
        if b.id in a.exit_lanes or b.id in a.entry_lanes:
            return False
        lo, hi = self.config.lane_width_range
        mid = b.points[len(b.points) // 2, :2]
        dist = float(np.min(np.linalg.norm(a.points[:, :2] - mid, axis=1)))
        return lo <= dist <= hi

    @cached_property
    def lane_changes(self) -> list[LaneChange]:
        """Switches between neighbour lanes (from the map), else `changing_lanes` agent labels."""
        if not self.scenario.road_map.lanes:
            return self._labelled_lane_changes()
        cfg = self.config
        by_id = self.scenario.road_map.by_id
        changes = []
        for a in np.flatnonzero(self.movers).tolist():
            lanes = self.lanes[a]
            runs = [
                (lane, s, e)
                for lane in np.unique(lanes[lanes >= 0]).tolist()
                for s, e in true_runs(lanes == lane, max_gap=2)
                if e - s >= cfg.min_lane_steps
            ]
            runs.sort(key=lambda r: r[1])
            for (la, _, ea), (lb, sb, _) in itertools.pairwise(runs):
                if la != lb and sb - ea <= 10 and self._neighbours(by_id[la], by_id[lb]):
                    if not self._confirmed(a, la, lb, sb):
                        continue
                    if changes and changes[-1].agent == a and sb - changes[-1].switch < cfg.lane_change_half_span:
                        continue  # one manoeuvre over several lane pieces
                    start = max(sb - cfg.lane_change_half_span, 0)
                    end = min(sb + cfg.lane_change_half_span, self.num_steps)
                    changes.append(LaneChange(a, sb, start, end, la, lb))
        return changes

    def _confirmed(self, a: int, from_lane: int, to_lane: int, switch: int) -> bool:
        """Whether a lane switch of agent `a` at step `switch` is a manoeuvre, not a flicker of the nearest lane:
        `a` does not stand all window, drives at a median speed of at least `lane_change_min_speed` within
        `lane_change_speed_steps` of the switch, and its signed offset from the lane left or the lane entered (each
        extended straight past its ends) changes by `lane_change_min_lateral` to `lane_change_max_lateral` between
        its first and last valid steps within `lane_change_lateral_steps` of the switch (larger changes come from
        lanes curving away, not from a move across one lane)."""
        cfg = self.config
        if self.static[a]:
            return False
        near = slice(max(switch - cfg.lane_change_speed_steps, 0), switch + cfg.lane_change_speed_steps + 1)
        speed = self.speed[a, near][self.valid[a, near]]
        if not speed.size or float(np.median(speed)) < cfg.lane_change_min_speed:
            return False
        lo = max(switch - cfg.lane_change_lateral_steps, 0)
        steps = lo + np.flatnonzero(self.valid[a, lo : switch + cfg.lane_change_lateral_steps + 1])
        if steps.size < 2:
            return False
        moves = [
            abs(_signed_offset(line, self.xy[a, steps[-1]]) - _signed_offset(line, self.xy[a, steps[0]]))
            for line in (self._lane_polylines[i][0] for i in (from_lane, to_lane) if i in self._lane_polylines)
        ]
        return bool(moves) and cfg.lane_change_min_lateral <= min(moves) and max(moves) <= cfg.lane_change_max_lateral

    def _labelled_lane_changes(self) -> list[LaneChange]:
        index = {int(i): n for n, i in enumerate(self.ids)}
        return [
            LaneChange(index[lab.track_id], (lab.start + lab.end) // 2, lab.start, lab.end, -1, -1)
            for lab in self.agent_labels
            if lab.key == "changing_lanes" and lab.track_id in index
        ]

    def is_merge(self, change: LaneChange) -> bool:
        """Whether the change leaves a lane that ends while the lane entered goes on: the lane left has no
        successors and the target lane has some or runs on past the left lane's end (so a map crop that cut both
        is no merge). A map without lane connectivity (nuScenes) shows no lane ending, so it has no merges."""
        by_id = self.scenario.road_map.by_id
        lane, target = by_id.get(change.from_lane), by_id.get(change.to_lane)
        if lane is None or target is None or lane.exit_lanes or not self.has_connectivity:
            return False
        if target.exit_lanes:
            return True
        end = lane.points[-1, :2]
        d = lane.points[-1, :2] - lane.points[max(len(lane.points) - 3, 0), :2]
        direction = d / max(float(np.linalg.norm(d)), 1e-6)
        return float((target.points[-1, :2] - end) @ direction) > self.config.lane_runs_on

    @cached_property
    def has_connectivity(self) -> bool:
        """Whether some lane of the map names a successor or a predecessor."""
        return any(lane.exit_lanes or lane.entry_lanes for lane in self.scenario.road_map.lanes)

    def from_other_road(self, change: LaneChange) -> bool:
        """Whether the lane left came from another road than the lane entered (an on-ramp's acceleration lane, not
        a lane drop): no lane before it lies beside a lane before the target lane, nor is one of those."""
        by_id = self.scenario.road_map.by_id
        lane, target = by_id.get(change.from_lane), by_id.get(change.to_lane)
        if lane is None or target is None or not lane.entry_lanes:
            return False
        beside = set()
        for e in target.entry_lanes:
            f = by_id.get(e)
            if f is not None:
                beside |= {n.feature_id for n in (*f.left_neighbors, *f.right_neighbors)}
        before = set(lane.entry_lanes)
        return not (beside | set(target.entry_lanes)) & before

    @cached_property
    def has_roundabout(self) -> bool:
        """Whether the map holds a ring: a chain of successor lanes shorter than `ring_length` back to its start
        that turns by a full circle one way, every lane of it (but those shorter than `ring_short_lane`) curving
        that way by at least `ring_min_curvature` (a loop of straight roads and turns around a block is none)."""
        cfg = self.config
        polylines = self._lane_polylines
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
        pts = np.concatenate([self._lane_polylines[i][0] for i in chain])
        radius = np.linalg.norm(pts - pts.mean(axis=0), axis=1)
        return float(radius.min()) >= self.config.ring_min_roundness * float(radius.max())

    def _lane_chain(self, lane_id: int, a: int, t: int) -> set[int]:
        """`lane_id` and its successors (junction lanes included) up to `target_lane_range` ahead of agent `a` at
        step `t`; at a split only the branches a's later trajectory runs along (all when it runs along none)."""
        polylines = self._lane_polylines
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
                driven = [n for n in nexts if self._near(polylines[n][0], later, self.config.target_lane_lateral)]
                nexts = driven or nexts
            for n in nexts:
                seen.add(n)
                stack.append((n, length, None))
        return seen

    @staticmethod
    def _near(points: np.ndarray, track: np.ndarray, radius: float) -> bool:
        """Whether some point of `track` lies within `radius` of `points`' polyline points."""
        step = max(len(points) // 16, 1)
        d = np.linalg.norm(points[::step, None, :] - track[None, :, :], axis=-1)
        return bool((d < radius + 0.5 * step).any())

    def leader_after(self, change: LaneChange) -> int:
        """The leader on the target lane right after the switch (agent index, -1 when none)."""
        return self._lane_leader(change.agent, min(change.switch + 1, self.num_steps - 1), change.to_lane)

    def former_leader(self, change: LaneChange) -> int:
        """The leader on the lane left right before the switch (agent index, -1 when none)."""
        return self._lane_leader(change.agent, max(change.switch - 1, 0), change.from_lane)

    def _lane_leader(self, a: int, t: int, lane_id: int) -> int:
        """The nearest vehicle or cyclist ahead of agent `a` at step `t` whose centre lies on lane `lane_id` or
        its successors along a's way (heading along them); a's leader on its own path where the map has no such
        lane."""
        if lane_id < 0 or lane_id not in self._lane_polylines:
            return int(self.leaders[a, t])
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
        polylines = self._lane_polylines
        chain = [polylines[i] for i in self._lane_chain(lane_id, a, t)]
        pts = np.concatenate([c[0] for c in chain])
        heads = np.concatenate([c[1] for c in chain])
        d = np.linalg.norm(self.xy[others, t][:, None, :] - pts[None], axis=-1)
        aligned = np.abs(wrap_angle(heads[None, :] - self.heading[others, t][:, None])) < cfg.lane_match_heading
        on = np.where(aligned, d, np.inf).min(axis=1) < cfg.target_lane_lateral
        if not on.any():
            return -1
        return int(others[on][np.argmin(dist[on])])

    @cached_property
    def overtakes(self) -> dict[LaneChange, Pair]:
        """Lane changes around a slower former leader that the changer then gets ahead of."""
        out = {}
        for change in self.lane_changes:
            if self.is_merge(change):
                continue
            b = self.former_leader(change)
            if b < 0:
                continue
            a = change.agent
            span = slice(change.start, change.switch + 1)
            both = self.valid[a, span] & self.valid[b, span]
            if not both.any() or self.speed[b, span][both].mean() >= self.speed[a, span][both].mean():
                continue
            rel = self.xy[a, change.switch :] - self.xy[b, change.switch :]
            head = self.heading[b, change.switch :]
            along = rel[:, 0] * np.cos(head) + rel[:, 1] * np.sin(head)
            ahead = np.flatnonzero(self.valid[a, change.switch :] & self.valid[b, change.switch :] & (along > 0))
            if ahead.size:
                out[change] = Pair(a, b, change.start, max(change.switch + int(ahead[0]) + 1, change.end))
        return out

    # ------------------------------------------------------------ held steps and junction yields
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
                on = self.lanes == lane.id
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
        (`continuations`, none on a signal-controlled approach); points [N, 2] and headings [N]."""
        path = self._yield_paths[a]
        real = path.points[path.real]
        last = np.flatnonzero(self.valid[a])[-1]
        conts = self.continuations(a) if self.config.continue_on_map and self.static[a] and self.held[a, last] else []
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
        path_b = self.paths[b]
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
        lead = self.leaders[a]
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
        paths = self.paths
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
    def _yield_paths(self) -> dict[int, Path]:
        return {a: p for a in self.paths if (p := self._path(a, 0.0, self.config.wait_extension)) is not None}

    @cached_property
    def _lane_polylines(self) -> dict[int, tuple[np.ndarray, np.ndarray]]:
        """Every lane (junction lanes included): points [N, 2] and tangent headings [N]."""
        out = {}
        for lane in self.scenario.road_map.lanes:
            if len(lane.points) >= 2:
                p = lane.points[:, :2]
                d = np.gradient(p, axis=0)
                out[lane.id] = (p, np.arctan2(d[:, 1], d[:, 0]))
        return out

    def continuations(self, a: int) -> list[np.ndarray]:
        """Map polylines [N, 2] an agent may drive on after its last valid step: the rest of its lane, then each
        chain of successor lanes up to `continuation_length` (empty when no lane matches, and when the way runs
        over a lane with a traffic light: there the light gives the right of way, see `red`)."""
        cfg = self.config
        steps = np.flatnonzero(self.valid[a])
        if steps.size == 0 or not self._lane_polylines:
            return []
        here, head = self.xy[a, steps[-1]], self.heading[a, steps[-1]]
        best = int(self._match(here[None], np.array([head]), exclude_junctions=False)[0])
        if best < 0 or best not in self._lane_polylines:
            return []
        best_k = int(np.argmin(np.linalg.norm(self._lane_polylines[best][0] - here, axis=1)))
        by_id = self.scenario.road_map.by_id
        signalled = {int(n) for n in self.scenario.traffic_lights.lane_ids}
        out = []
        stack = [(self._lane_polylines[best][0][best_k:], by_id[best])]
        while stack:
            pts, lane = stack.pop()
            length = float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum()) if len(pts) > 1 else 0.0
            nexts = [n for n in lane.exit_lanes if n in self._lane_polylines]
            if signalled & {lane.id, *nexts}:
                return []  # a signal-controlled approach: the light gives the right of way (see `red`)
            if length >= cfg.continuation_length or not nexts or len(out) + len(stack) > 16:
                out.append(pts)
                continue
            for n in nexts:
                stack.append((np.concatenate([pts, self._lane_polylines[n][0]]), by_id[n]))
        return out

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

    # ------------------------------------------------------------ pedestrians and crosswalks
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
    def pedestrian_yields(self) -> list[Pair]:
        """Held vehicles whose look-ahead runs over a crosswalk with a pedestrian on it, to the nearest one."""
        cfg = self.config
        hits: dict[tuple[int, int], list[int]] = {}
        ahead = np.linspace(0.5, cfg.ped_lookahead, 24)
        for c, cw in enumerate(self.crosswalks):
            occupied = self.ped_on_crosswalk[c].any(axis=0)
            if not occupied.any():
                continue
            for v in np.flatnonzero(self.movers).tolist():
                steps = np.flatnonzero(self.held[v] & occupied)
                if steps.size == 0:
                    continue
                reach = 0.5 * self.length[v, steps][:, None] + ahead[None, :]
                direction = np.stack([np.cos(self.heading[v, steps]), np.sin(self.heading[v, steps])], axis=-1)
                probes = self.xy[v, steps][:, None, :] + reach[..., None] * direction[:, None, :]
                over = cw.contains_points(probes.reshape(-1, 2)).reshape(len(steps), -1).any(axis=1)
                for t in steps[over].tolist():
                    peds = np.flatnonzero(self.ped_on_crosswalk[c, :, t])
                    p = int(peds[np.argmin(np.linalg.norm(self.xy[peds, t] - self.xy[v, t], axis=1))])
                    hits.setdefault((v, p), []).append(t)
        out = []
        for (v, p), steps in sorted(hits.items()):
            mask = np.zeros(self.num_steps, bool)
            mask[steps] = True
            out.extend(Pair(v, p, s, e) for s, e in true_runs(mask, cfg.min_event_steps, cfg.merge_gap))
        return out

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

    @cached_property
    def pedestrian_waits(self) -> list[tuple[Pair, Pair]]:
        """(P yields to V over its wait, V passes P over its steps on the crosswalk) for pedestrians standing
        next to a crosswalk they then step onto, for each vehicle on that crosswalk during the wait."""
        cfg = self.config
        out = []
        on_any = self.ped_on_crosswalk.any(axis=0) if len(self.crosswalks) else np.zeros(self.valid.shape, bool)
        for p in self._peds.tolist():
            standing = self.valid[p] & (self.speed[p] <= cfg.stopped_speed) & ~on_any[p]
            for w0, w1 in true_runs(standing):
                if w1 - w0 < cfg.min_event_steps:
                    continue
                later = self.ped_on_crosswalk[:, p, w1 : w1 + cfg.wait_to_cross_steps].any(axis=1)
                if w1 >= self.num_steps and not later.any():
                    later = self._crosswalk_near(self.xy[p, w1 - 1])
                for c in np.flatnonzero(later).tolist():
                    for v in np.flatnonzero(self.movers).tolist():
                        steps = self._on_crosswalk(c, v, w0, w1)
                        if steps.size:
                            out.append((Pair(p, v, w0, w1), Pair(v, p, int(steps[0]), int(steps[-1]) + 1)))
        return out


# ---------------------------------------------------------------- rules


class InteractionRule(abc.ABC):
    """Detects the labels of one interaction type in a scene."""

    name: ClassVar[str]
    type: ClassVar[InteractionType]

    @abc.abstractmethod
    def detect(self, scene: SceneGeometry) -> list[InteractionLabel]:
        """The labels of this rule's type in `scene` (window filtering happens afterwards)."""


RULES: Registry[InteractionRule] = Registry("interaction rule")


def _label(scene: SceneGeometry, agent: int, other: int, subtype: str, start: int, end: int) -> InteractionLabel:
    other_id = int(scene.ids[other]) if other >= 0 else -1
    return InteractionLabel(
        int(scene.ids[agent]),
        other_id,
        SUBTYPES_BY_ID[subtype],
        LabelSource.DETECTOR,
        int(start),
        int(max(end, start + 1)),
    )


@RULES.register
class LaneChangeRule(InteractionRule):
    """A switch to a neighbour lane, with the leader on the target lane (or the overtaken agent)."""

    name = "lane_change"
    type = InteractionType.LANE_CHANGE

    def detect(self, scene: SceneGeometry) -> list[InteractionLabel]:
        labels = []
        for change in scene.lane_changes:
            if scene.is_merge(change):
                continue
            overtake = scene.overtakes.get(change)
            if overtake is not None:
                labels.append(
                    _label(scene, change.agent, overtake.other, "lane_change/for_overtaking", change.start, change.end)
                )
                continue
            other = scene.leader_after(change)
            labels.append(_label(scene, change.agent, other, self._subtype(scene, change), change.start, change.end))
        return labels

    @staticmethod
    def _subtype(scene: SceneGeometry, change: LaneChange) -> str:
        before = scene.former_leader(change)
        if before >= 0 and scene.speed[before, change.switch] < scene.speed[change.agent, change.switch]:
            return "lane_change/avoiding_slower_traffic"
        heads = scene.heading[change.agent][scene.valid[change.agent]]
        if heads.size and np.abs(wrap_angle(heads - heads[0])).max() > math.radians(45.0):
            return "lane_change/for_turn_or_exit"
        return "lane_change/with_lead_or_trail"


@RULES.register
class FollowingRule(InteractionRule):
    """At least 1 s behind the same leader on one's own path."""

    name = "following"
    type = InteractionType.FOLLOWING

    def detect(self, scene: SceneGeometry) -> list[InteractionLabel]:
        return [_label(scene, p.agent, p.other, self._subtype(scene, p), p.start, p.end) for p in scene.follows]

    @staticmethod
    def _subtype(scene: SceneGeometry, pair: Pair) -> str:
        cfg = scene.config
        s = slice(pair.start, pair.end)
        speed = scene.speed[pair.agent, s]
        both = scene.valid[pair.agent, s] & scene.valid[pair.other, s]
        if (both & (speed <= cfg.stopped_speed)).any():
            return "following/stopping_behind_lead"
        speed = np.where(both, speed, 0.0)
        gap = np.linalg.norm(scene.xy[pair.agent, s] - scene.xy[pair.other, s], axis=1)
        gap -= 0.5 * (scene.length[pair.agent, s] + scene.length[pair.other, s])
        close = both & (speed >= cfg.tailgating_speed) & (gap < cfg.tailgating_headway_s * np.maximum(speed, 1e-3))
        if close.sum() >= cfg.min_follow_steps:
            return "following/tailgating"
        earlier = scene.speed[pair.agent, max(pair.start - 30, 0) : pair.start + 1]
        lead = scene.speed[pair.other, s][both].mean() if both.any() else 0.0
        if earlier.size and 0.5 <= lead <= cfg.slow_lead_ratio * earlier.max():
            return "following/slow_lead"
        return "following/with_lead"


def _roundabout(scene: SceneGeometry) -> bool:
    return scene.has_roundabout


@RULES.register
class YieldingRule(InteractionRule):
    """Held before a crossing path's conflict point, or before a crosswalk in use; pedestrians waiting."""

    name = "yielding"
    type = InteractionType.YIELDING

    def detect(self, scene: SceneGeometry) -> list[InteractionLabel]:
        junction = "yielding/roundabout" if _roundabout(scene) else "yielding/intersection"
        changing = {c.agent for c in scene.lane_changes}
        labels = []
        for p in scene.vehicle_yields:
            sub = "yielding/to_merging_or_lane_change" if p.other in changing and not _roundabout(scene) else junction
            labels.append(_label(scene, p.agent, p.other, sub, p.start, p.end))
        labels += [
            _label(scene, p.agent, p.other, "yielding/to_pedestrian", p.start, p.end) for p in scene.pedestrian_yields
        ]
        labels += [
            _label(scene, w.agent, w.other, "yielding/pedestrian_to_vehicle", w.start, w.end)
            for w, _ in scene.pedestrian_waits
        ]
        return labels


@RULES.register
class PassingRule(InteractionRule):
    """The other side of every yield: going first while another agent waits."""

    name = "passing"
    type = InteractionType.PASSING

    def detect(self, scene: SceneGeometry) -> list[InteractionLabel]:
        labels = []
        for p in scene.vehicle_yields:
            if _roundabout(scene):
                sub = "passing/roundabout"
            elif scene.types[p.other] == AgentType.CYCLIST:
                sub = "passing/vru_crossing"
            else:
                sub = "passing/intersection_with_yielding"
            labels.append(_label(scene, p.other, p.agent, sub, p.start, p.end))
        labels += [
            _label(scene, p.other, p.agent, "passing/vru_crossing", p.start, p.end) for p in scene.pedestrian_yields
        ]
        labels += [
            _label(scene, v.agent, v.other, "passing/pedestrian", v.start, v.end) for _, v in scene.pedestrian_waits
        ]
        return labels


@RULES.register
class OvertakingRule(InteractionRule):
    """A lane change around a slower leader that ends with the changer ahead of it."""

    name = "overtaking"
    type = InteractionType.OVERTAKING

    def detect(self, scene: SceneGeometry) -> list[InteractionLabel]:
        labels = []
        for p in scene.overtakes.values():
            top = scene.speed[p.agent, p.start : p.end][scene.valid[p.agent, p.start : p.end]]
            fast = top.size and top.max() >= scene.config.high_speed
            sub = "overtaking/high_speed" if fast else "overtaking/standard"
            labels.append(_label(scene, p.agent, p.other, sub, p.start, p.end))
        return labels


@RULES.register
class MergingRule(InteractionRule):
    """A lane change out of a lane that ends, with the leader on the target lane."""

    name = "merging"
    type = InteractionType.MERGING

    def detect(self, scene: SceneGeometry) -> list[InteractionLabel]:
        labels = []
        for change in scene.lane_changes:
            if not scene.is_merge(change):
                continue
            a, s = change.agent, change.switch
            onramp = scene.from_other_road(change)
            before = scene.speed[a, max(s - 30, 0) : s][scene.valid[a, max(s - 30, 0) : s]]
            during = scene.speed[a, change.start : change.end][scene.valid[a, change.start : change.end]]
            if before.size and before.min() < scene.config.held_speed:
                sub = "merging/late"
            elif onramp and during.size > 1 and during[-1] - during[0] >= 2.0:
                sub = "merging/on_ramp_accelerating"
            else:
                sub = "merging/standard" if onramp else "merging/lane_reduction"
            labels.append(_label(scene, a, scene.leader_after(change), sub, change.start, change.end))
        return labels


def detect_interactions(
    scenario: Scenario,
    agent_labels: Sequence[AgentLabel] = (),
    config: DetectorConfig | None = None,
    map_index: MapIndex | None = None,
) -> tuple[InteractionLabel, ...]:
    """Interaction labels of `scenario` from its trajectories and map by every registered rule (source DETECTOR);
    pass the scene's `map_index` to share the one the heuristic labeler used."""
    scene = SceneGeometry(scenario, agent_labels, config or DetectorConfig(), map_index)
    labels = [lab for cls in RULES.classes() for lab in cls().detect(scene)]
    min_steps = round(scene.config.min_window_s / STEP_SECONDS)
    return tuple(sorted(filter_to_window(labels, scenario, min_steps), key=label_sort_key))
