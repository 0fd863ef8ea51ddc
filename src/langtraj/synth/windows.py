"""Cutting 9.1 s Scenario windows out of one simulation, around the network's interesting places.

A window is 91 steps (11 history, 80 future) starting every `stride_s` after the warm-up, at every
interest centre. It keeps the agents that come within the centre's radius during the window (10 to 128
of them, nearest first), its interacting pair as objects of interest, and is dropped when any of its
agents was teleported or collided in it, or two vehicle boxes overlap.

See docs/data.md.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from langtraj.scenario.model import (
    FUTURE_STEPS,
    HISTORY_STEPS,
    STEP_SECONDS,
    Agents,
    BehaviorEvent,
    RoadMap,
    Scenario,
    TrafficLights,
)
from langtraj.scenario.types import NUM_STATE_FIELDS, AgentType, StateField, TrafficLightState
from langtraj.synth.network import InterestCentre
from langtraj.synth.records import Track

INTERACTION_RANK = {
    "yield": 0,
    "go_first": 1,
    "yield_to_pedestrian": 2,
    "lane_change": 3,
    "ped_crossing": 4,
    "ped_waiting": 5,
}
"""Event kinds that make a window interesting, best first (`follow` alone does not)."""

MIN_INTERACTION_STEPS = 10
"""An interaction must last at least 1 s within the window's current and future steps to count."""

SUMO_SIGNAL_STATES = {
    ord("r"): TrafficLightState.STOP,
    ord("y"): TrafficLightState.CAUTION,
    ord("u"): TrafficLightState.CAUTION,
    ord("G"): TrafficLightState.GO,
    ord("g"): TrafficLightState.GO,
    ord("s"): TrafficLightState.STOP,
    ord("o"): TrafficLightState.FLASHING_CAUTION,
    ord("O"): TrafficLightState.UNKNOWN,
}
"""SUMO link state characters to WOMD lane states ('G' = protected green, 'g' = permissive green)."""

_SIGNAL_LOOKUP = np.zeros(256, np.int8)  # SUMO state byte -> TrafficLightState (UNKNOWN for others)
for _char, _state in SUMO_SIGNAL_STATES.items():
    _SIGNAL_LOOKUP[_char] = _state


@dataclass(frozen=True)
class WindowConfig:
    """How windows are cut and filtered."""

    history: int = HISTORY_STEPS
    future: int = FUTURE_STEPS
    stride_s: float = 2.5
    warmup_s: float = 60.0
    min_agents: int = 10
    max_agents: int = 128
    agent_radius_m: float = 80.0
    """Agents within max(this, the centre's radius) of the centre at some step belong to the window."""
    map_margin_m: float = 30.0
    overlap_shrink: float = 0.05
    """m shaved off each box side before the overlap test (SUMO boxes touch when queued)."""
    max_tracks_to_predict: int = 8
    require_interaction: bool = True
    decision_lead_s: tuple[float, float] = (0.5, 5.0)
    """Windows are first cut so that a driver's decision (`decision` events) near the centre falls this long
    after the current step (history cannot reveal it); the regular grid fills in after them."""

    @property
    def length(self) -> int:
        return self.history + self.future


@dataclass(frozen=True)
class SignalTable:
    """Traffic-light links of the network and their recorded states (uint8 SUMO characters [T, L])."""

    lane_ids: np.ndarray  # int64 [L] map feature ids of the controlled lanes
    stop_points: np.ndarray  # float64 [L, 3]
    states: np.ndarray  # uint8 [num_steps + 1, L]


@dataclass(frozen=True)
class RunData:
    """One simulation, ready to cut: clean tracks, global events, collisions and teleports by track id."""

    tracks: tuple[Track, ...]
    events: tuple[BehaviorEvent, ...]
    num_steps: int
    collisions: tuple[tuple[int, int, int], ...]  # (step, track id, track id)
    teleports: tuple[tuple[int, int], ...]  # (step, track id)
    signals: SignalTable


@dataclass(frozen=True)
class Rejection:
    """Why a window candidate was dropped (counted in the manifest)."""

    reason: str


class _Dense:
    """All tracks on one global time axis: xy [N, T, 2] (NaN where invalid) for fast window queries."""

    def __init__(self, tracks: Sequence[Track], num_steps: int):
        n = len(tracks)
        self.xy = np.full((n, num_steps + 1, 2), np.nan, np.float32)
        self.start = np.array([t.start for t in tracks], np.int64)
        self.stop = np.array([t.stop for t in tracks], np.int64)
        for i, t in enumerate(tracks):
            seg = np.where(t.valid[:, None], t.xy, np.nan)
            self.xy[i, t.start : t.stop] = seg


def _obb_overlap(c1, h1, s1, c2, h2, s2) -> np.ndarray:
    """Separating-axis test for oriented boxes; arrays broadcast over leading dims, sizes are (l, w)."""
    corners_axes = []
    for h in (h1, h2):
        corners_axes.append(np.stack([np.cos(h), np.sin(h)], -1))
        corners_axes.append(np.stack([-np.sin(h), np.cos(h)], -1))
    d = c2 - c1
    separated = np.zeros(np.broadcast_shapes(d.shape[:-1]), bool)
    u1, v1, u2, v2 = corners_axes
    for axis in corners_axes:
        r1 = 0.5 * s1[..., 0] * np.abs((u1 * axis).sum(-1)) + 0.5 * s1[..., 1] * np.abs((v1 * axis).sum(-1))
        r2 = 0.5 * s2[..., 0] * np.abs((u2 * axis).sum(-1)) + 0.5 * s2[..., 1] * np.abs((v2 * axis).sum(-1))
        separated |= np.abs((d * axis).sum(-1)) > r1 + r2
    return ~separated


def boxes_overlap(states: np.ndarray, valid: np.ndarray, types: np.ndarray, shrink: float) -> bool:
    """True when two vehicle/cyclist boxes (shrunk by `shrink` per side) overlap at some valid step."""
    idx = np.flatnonzero(types != AgentType.PEDESTRIAN)
    if len(idx) < 2:
        return False
    s = states[idx]
    v = valid[idx]
    i, j = np.triu_indices(len(idx), 1)
    xy = s[..., :2].astype(np.float64)
    size = np.maximum(s[..., [StateField.LENGTH, StateField.WIDTH]].astype(np.float64) - 2 * shrink, 0.1)
    reach = 0.5 * np.hypot(size[..., 0], size[..., 1])
    both = v[i] & v[j]
    close = both & (np.linalg.norm(xy[i] - xy[j], axis=-1) < reach[i] + reach[j])
    if not close.any():
        return False
    pi, ti = np.nonzero(close)
    a, b = i[pi], j[pi]
    head = s[..., StateField.HEADING].astype(np.float64)
    return bool(_obb_overlap(xy[a, ti], head[a, ti], size[a, ti], xy[b, ti], head[b, ti], size[b, ti]).any())


class WindowCutter:
    """Cuts windows out of one simulation (see module docstring)."""

    def __init__(self, run: RunData, config: WindowConfig):
        self.run = run
        self.config = config
        self.dense = _Dense(run.tracks, run.num_steps)
        self.by_id = {t.track_id: t for t in run.tracks}
        self.index_of = {t.track_id: i for i, t in enumerate(run.tracks)}
        self.interactions = [e for e in run.events if e.kind in INTERACTION_RANK]

    def starts(self) -> range:
        """Global first steps of all windows (history starts after the warm-up)."""
        cfg = self.config
        first = round(cfg.warmup_s / STEP_SECONDS)
        stride = max(1, round(cfg.stride_s / STEP_SECONDS))
        return range(first, self.run.num_steps + 1 - cfg.length + 1, stride)

    def candidates(self, centres: Sequence[InterestCentre]) -> Iterator[tuple[int, int]]:
        """(centre index, start step) pairs: first those that put a decision near the centre inside
        `decision_lead_s` after the current step, then the regular grid; each in time order, centres
        interleaved."""
        yield from self.decision_candidates(centres)
        for start in self.starts():
            for c in range(len(centres)):
                yield c, start

    def decision_candidates(self, centres: Sequence[InterestCentre]) -> list[tuple[int, int]]:
        """Starts putting each executed decision, made within a centre's radius, at the middle of
        `decision_lead_s` after the current step (one per decision; the first centre that holds it)."""
        cfg = self.config
        grid = self.starts()
        if not len(grid):
            return []
        lead = round(0.5 * sum(cfg.decision_lead_s) / STEP_SECONDS)
        out = []
        for e in self.run.events:
            if e.kind != "decision" or not e.attributes.get("executed", False):
                continue
            start = int(e.attributes["decision_step"]) - lead - (cfg.history - 1)
            if not grid.start <= start <= grid[-1]:
                continue
            track = self.by_id[e.track_id]
            x, y = track.xy[track.local(e.start)]
            for c, centre in enumerate(centres):
                if np.hypot(x - centre.x, y - centre.y) <= max(centre.radius, cfg.agent_radius_m):
                    out.append((start, c))
                    break
        return [(c, start) for start, c in sorted(set(out))]

    def _agents_near(self, centre: InterestCentre, start: int) -> tuple[np.ndarray, np.ndarray]:
        """Indices of tracks within the radius at some step of the window, and their nearest distance."""
        stop = start + self.config.length
        active = np.flatnonzero((self.dense.start < stop) & (self.dense.stop > start))
        xy = self.dense.xy[active, start:stop]
        dist = np.hypot(xy[..., 0] - centre.x, xy[..., 1] - centre.y)
        nearest = np.nanmin(np.where(np.isnan(dist), np.inf, dist), axis=1)
        inside = nearest <= max(centre.radius, self.config.agent_radius_m)
        return active[inside], nearest[inside]

    def _best_interaction(self, ids: set[int], start: int) -> BehaviorEvent | None:
        cfg = self.config
        current = start + cfg.history - 1
        stop = start + cfg.length
        best, best_key = None, None
        for e in self.interactions:
            if min(e.end, stop) - max(e.start, current) < MIN_INTERACTION_STEPS or e.track_id not in ids:
                continue
            if e.other_id >= 0 and e.other_id not in ids:
                continue
            key = (INTERACTION_RANK[e.kind], abs(e.start - current), e.track_id)
            if best_key is None or key < best_key:
                best, best_key = e, key
        return best

    def _order(self, members: np.ndarray, nearest: np.ndarray, current: int, first: Sequence[int]) -> np.ndarray:
        """Members ordered: objects of interest, then valid at the current step by distance, then the rest."""
        at_current = ~np.isnan(self.dense.xy[members, current, 0])
        is_first = np.isin([self.run.tracks[m].track_id for m in members], list(first))
        priority = np.where(is_first, 0, np.where(at_current, 1, 2))
        order = np.lexsort((nearest, priority))
        return members[order][: self.config.max_agents]

    def window_xy(self, members: np.ndarray, start: int) -> np.ndarray:
        """Positions [M, T, 2] of `members` during the window starting at `start` (NaN where invalid)."""
        return self.dense.xy[members, start : start + self.config.length]

    def cut(
        self, centre: InterestCentre, start: int
    ) -> tuple[np.ndarray, np.ndarray, BehaviorEvent | None] | Rejection:
        """Members (track indices, in scene order) and objects of interest of one window, or why not."""
        cfg = self.config
        members, nearest = self._agents_near(centre, start)
        if len(members) < cfg.min_agents:
            return Rejection("too_few_agents")
        ids = {self.run.tracks[m].track_id for m in members}
        event = self._best_interaction(ids, start)
        if event is None and cfg.require_interaction:
            return Rejection("no_interaction")
        ooi = [] if event is None else [event.track_id] + ([event.other_id] if event.other_id >= 0 else [])
        members = self._order(members, nearest, start + cfg.history - 1, ooi)  # objects of interest first
        stop = start + cfg.length
        kept = {self.run.tracks[m].track_id for m in members}
        if any(start <= s < stop and (a in kept or b in kept) for s, a, b in self.run.collisions):
            return Rejection("collision")
        if any(start <= s < stop and a in kept for s, a in self.run.teleports):
            return Rejection("teleport")
        return members, np.array([self.index_of[i] for i in ooi], np.int64), event

    def scenario(
        self,
        members: np.ndarray,
        ooi: np.ndarray,
        start: int,
        scenario_id: str,
        road_map: RoadMap,
        metadata: Mapping[str, object],
    ) -> Scenario | Rejection:
        """The Scenario of a cut window (map already cropped), or a Rejection for overlap / no SDC."""
        cfg = self.config
        length = cfg.length
        tracks = [self.run.tracks[m] for m in members]
        states = np.zeros((len(tracks), length, NUM_STATE_FIELDS), np.float32)
        valid = np.zeros((len(tracks), length), bool)
        for a, t in enumerate(tracks):
            lo, hi = max(start, t.start), min(start + length, t.stop)
            src = slice(lo - t.start, hi - t.start)
            dst = slice(lo - start, hi - start)
            poses = np.concatenate([t.xy[src], t.heading[src, None], t.speed[src, None]], axis=-1)
            Agents.write_poses(states[a, dst], poses, wrap=False)  # headings kept bit for bit as the track holds them
            states[a, dst, StateField.LENGTH] = t.size[0]
            states[a, dst, StateField.WIDTH] = t.size[1]
            states[a, dst, StateField.HEIGHT] = t.size[2]
            valid[a, dst] = t.valid[src]
        types = np.array([t.agent_type for t in tracks], np.int8)
        if boxes_overlap(states, valid, types, cfg.overlap_shrink):
            return Rejection("overlap")
        position = {int(m): a for a, m in enumerate(members)}
        ooi_local = np.array([position[int(m)] for m in ooi], np.int64)
        sdc = self._pick_sdc(types, valid, ooi_local)
        if sdc < 0:
            return Rejection("no_sdc")
        ids = np.array([t.track_id for t in tracks], np.int64)
        tracks_to_predict = self._tracks_to_predict(valid, ooi_local, sdc)
        agents = Agents(
            ids=ids,
            types=types,
            states=states,
            valid=valid,
            tracks_to_predict=tracks_to_predict,
            prediction_difficulty=np.zeros(len(tracks_to_predict), np.int8),
            objects_of_interest=ooi_local,
        )
        return Scenario(
            scenario_id=scenario_id,
            timestamps=np.round(np.arange(length) * STEP_SECONDS, 6),
            current_index=cfg.history - 1,
            sdc_index=sdc,
            agents=agents,
            road_map=road_map,
            traffic_lights=self._lights(start, {f.id for f in road_map.features}),
            events=self._events(set(ids.tolist()), start),
            metadata=dict(metadata),
        )

    def _pick_sdc(self, types: np.ndarray, valid: np.ndarray, ooi: np.ndarray) -> int:
        """A vehicle valid at every step: the first such object of interest, else the one nearest the others."""
        full = valid.all(axis=1) & (types == AgentType.VEHICLE)
        for a in ooi.tolist():
            if full[a]:
                return int(a)
        candidates = np.flatnonzero(full)
        if len(candidates) == 0:
            return -1
        return int(candidates[0])  # members are ordered nearest-first after the objects of interest

    def _tracks_to_predict(self, valid: np.ndarray, ooi: np.ndarray, sdc: int) -> np.ndarray:
        """Objects of interest first, then agents valid at the current and the last step, nearest first."""
        cfg = self.config
        chosen = [int(a) for a in ooi if valid[a, cfg.history - 1]]
        for a in range(len(valid)):
            if len(chosen) >= cfg.max_tracks_to_predict:
                break
            if a not in chosen and a != sdc and valid[a, cfg.history - 1] and valid[a, -1]:
                chosen.append(a)
        return np.array(chosen[: cfg.max_tracks_to_predict], np.int64)

    def _lights(self, start: int, feature_ids: set[int]) -> TrafficLights:
        table = self.run.signals
        keep = np.array([int(i) in feature_ids for i in table.lane_ids], bool)
        raw = table.states[start : start + self.config.length][:, keep]
        states = _SIGNAL_LOOKUP[raw]
        return TrafficLights(
            lane_ids=table.lane_ids[keep],
            states=states,
            valid=states != TrafficLightState.UNKNOWN,
            stop_points=table.stop_points[keep],
        )

    def _events(self, ids: set[int], start: int) -> tuple[BehaviorEvent, ...]:
        """Events of the window's agents (other agent in the window or none), clipped and re-based."""
        stop = start + self.config.length
        out = []
        for e in self.run.events:
            if e.end <= start or e.start >= stop or e.track_id not in ids:
                continue
            if e.other_id >= 0 and e.other_id not in ids:
                continue
            attributes = dict(e.attributes)
            for key in [k for k in attributes if k.endswith("_step") and isinstance(attributes[k], int)]:
                attributes[key] = int(attributes[key]) - start  # steps of the run -> steps of the window
            if e.start < start:
                attributes["clipped_start"] = True
            if e.end > stop:
                attributes["clipped_end"] = True
            lo, hi = max(e.start, start) - start, min(e.end, stop) - start
            out.append(BehaviorEvent(e.kind, e.track_id, lo, hi, e.other_id, attributes))
        return tuple(out)
