"""Lane changes, merges and overtakes for the interaction detector (docs/interdrive.md, 'Interaction labels').

A lane change is a switch of a mover's map lane (see `LaneGeometry.per_step`) to a neighbour lane
(`MapIndex.neighbor_side`), confirmed as a manoeuvre; the record is the labeler's `roads.records.LaneChange`.
"""

from __future__ import annotations

import itertools
import math
from functools import cached_property

import numpy as np

from langtraj.interdrive.detector.arrays import SceneArrays
from langtraj.interdrive.detector.lanes import LaneGeometry
from langtraj.interdrive.detector.parts import Pair, ScenePart
from langtraj.interdrive.labels import AgentLabel
from langtraj.roads import LaneChange
from langtraj.runs import true_runs


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


class LaneChangeGeometry(ScenePart):
    """The lane changes of one scene, which of them are merges and overtakes, and the leaders around them; from the
    map lanes of `lanes`, else from the `changing_lanes` labels among `agent_labels`."""

    def __init__(self, arrays: SceneArrays, lanes: LaneGeometry, agent_labels: tuple[AgentLabel, ...]):
        super().__init__(arrays)
        self.lanes = lanes
        self.agent_labels = agent_labels

    def _neighbours(self, from_lane: int, to_lane: int) -> bool:
        """Whether map lanes `from_lane` and `to_lane` (feature ids) are side by side."""
        index = self.map_index
        row = index.lane_row
        # Per lane pair, and a wider band between lane vertices (see `MapIndex.neighbor_side`): tuned against SUMO's
        # lane changes, where the labeler's per-map lists and 2.5-4.5 m at the switch point are tuned on its labels.
        side = index.neighbor_side(row[from_lane], row[to_lane], band=self.config.lane_width_range, per_lane=True)
        return side is not None

    @cached_property
    def lane_changes(self) -> list[LaneChange]:
        """Switches between neighbour lanes (from the map), else `changing_lanes` agent labels."""
        if not self.scenario.road_map.lanes:
            return self._labelled_lane_changes()
        cfg = self.config
        changes = []
        for a in np.flatnonzero(self.movers).tolist():
            lanes = self.lanes.per_step[a]
            runs = [
                (lane, s, e)
                for lane in np.unique(lanes[lanes >= 0]).tolist()
                for s, e in true_runs(lanes == lane, max_gap=2)
                if e - s >= cfg.min_lane_steps
            ]
            runs.sort(key=lambda r: r[1])
            for (la, _, ea), (lb, sb, _) in itertools.pairwise(runs):
                if la != lb and sb - ea <= 10 and self._neighbours(la, lb):
                    if not self._confirmed(a, la, lb, sb):
                        continue
                    if changes and changes[-1].agent == a and sb - changes[-1].switch < cfg.lane_change_half_span:
                        continue  # one manoeuvre over several lane pieces
                    start = max(sb - cfg.lane_change_half_span, 0)
                    end = min(sb + cfg.lane_change_half_span, self.num_steps)
                    changes.append(LaneChange(a, la, lb, sb, start, end))
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
        polylines = self.lanes.polylines
        moves = [
            abs(_signed_offset(line, self.xy[a, steps[-1]]) - _signed_offset(line, self.xy[a, steps[0]]))
            for line in (polylines[i][0] for i in (from_lane, to_lane) if i in polylines)
        ]
        return bool(moves) and cfg.lane_change_min_lateral <= min(moves) and max(moves) <= cfg.lane_change_max_lateral

    def _labelled_lane_changes(self) -> list[LaneChange]:
        index = {int(i): n for n, i in enumerate(self.ids)}
        return [
            LaneChange(index[lab.track_id], -1, -1, (lab.start + lab.end) // 2, lab.start, lab.end)
            for lab in self.agent_labels
            if lab.key == "changing_lanes" and lab.track_id in index
        ]

    def is_merge(self, change: LaneChange) -> bool:
        """Whether the change leaves a lane that ends while the lane entered goes on: the lane left has no
        successors and the target lane has some or runs on past the left lane's end (so a map crop that cut both
        is no merge). A map without lane connectivity (nuScenes) shows no lane ending, so it has no merges."""
        by_id = self.scenario.road_map.by_id
        lane, target = by_id.get(change.from_lane), by_id.get(change.to_lane)
        if lane is None or target is None or lane.exit_lanes or not self.lanes.has_connectivity:
            return False
        if target.exit_lanes:
            return True
        end = lane.points[-1, :2]
        d = lane.points[-1, :2] - lane.points[max(len(lane.points) - 3, 0), :2]
        direction = d / max(float(np.linalg.norm(d)), 1e-6)
        return float((target.points[-1, :2] - end) @ direction) > self.config.lane_runs_on

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

    def leader_after(self, change: LaneChange) -> int:
        """The leader on the target lane right after the switch (agent index, -1 when none)."""
        return self.lanes.leader(change.agent, min(change.switch + 1, self.num_steps - 1), change.to_lane)

    def follower_after(self, change: LaneChange) -> int:
        """The nearest vehicle or cyclist behind the changer right after the switch, on the target lane or a lane
        leading into it, its front bumper behind the changer's rear by at most `cut_in_range` or `cut_in_headway_s` at
        its speed (agent index, -1 when none): the one a cut-in lands in front of, closer than the two-second rule
        keeps. One still beside the changer (bumpers overlapping) is side-swiped, not cut in on."""
        a, t = change.agent, min(change.switch + 1, self.num_steps - 1)
        lane = self.scenario.road_map.by_id.get(change.to_lane)
        if lane is None or not self.valid[a, t]:
            return -1
        others = np.flatnonzero(self.movers & self.valid[:, t])
        others = others[(others != a) & np.isin(self.lanes.per_step[others, t], [lane.id, *lane.entry_lanes])]
        head = self.heading[a, t]
        rel = self.xy[others, t] - self.xy[a, t]
        behind = -(rel[:, 0] * math.cos(head) + rel[:, 1] * math.sin(head))
        gap = behind - 0.5 * (self.length[others, t] + self.length[a, t])
        cfg = self.config
        keep = (gap > 0) & (gap <= np.maximum(cfg.cut_in_range, cfg.cut_in_headway_s * self.speed[others, t]))
        return int(others[keep][np.argmin(behind[keep])]) if keep.any() else -1

    @cached_property
    def cut_ins(self) -> list[tuple[LaneChange, int]]:
        """Every cut-in, each a lane change or merge (a merge just ahead of a vehicle cuts in front of it too; overtakes
        left out) with the agent index of the vehicle that then follows in the target lane (`follower_after`)."""
        out = []
        for change in self.lane_changes:
            if change in self.overtakes:
                continue
            trail = self.follower_after(change)
            if trail >= 0:
                out.append((change, trail))
        return out

    def former_leader(self, change: LaneChange) -> int:
        """The leader on the lane left right before the switch (agent index, -1 when none)."""
        return self.lanes.leader(change.agent, max(change.switch - 1, 0), change.from_lane)

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
