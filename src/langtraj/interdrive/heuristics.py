"""Heuristic single-agent labels (InterDrive 'Heuristic Annotation Process') over a scene's future window;
docs/interdrive.md describes them and docs/benchmarks.md ('InterDrive labels') measures them.

Every agent valid at the current step and over at least `HeuristicConfig.min_future_fraction` of the future
steps [current_index, num_steps) gets the labels whose rule holds, each with the window steps [start, end)
where it holds, so prompts can order them. Speed and acceleration come from positions (gaps filled
linearly, then smoothed), not from the velocity fields. Each label (or small family) is one `LabelRule`
registered in `LABEL_RULES`; `label_agents` runs them all. Where the map lacks what a rule needs (lanes,
connectivity, neighbour lists, road edges, crosswalks) the rule returns `Undecided` naming it. Lane primitives
shared with the interaction detector (`LaneChange`, neighbour lanes, the road-side test of parked vehicles) are in
`mapindex`.
"""

from __future__ import annotations

import itertools
import math
from abc import ABC, abstractmethod
from collections.abc import Iterator
from dataclasses import dataclass, fields
from functools import cached_property
from typing import ClassVar

import numpy as np

from langtraj.angles import wrap_angle
from langtraj.interdrive.labels import AgentLabel, Undecided
from langtraj.interdrive.mapindex import LaneChange, LaneMatch, MapIndex
from langtraj.registry import Registry
from langtraj.runs import true_runs, value_runs
from langtraj.scenario.model import Scenario
from langtraj.scenario.types import AgentType


@dataclass(frozen=True)
class HeuristicConfig:
    """Every threshold of the heuristic labeler; units: m, s, m/s, m/s^2, rad."""

    min_future_fraction: float = 0.5
    """Share of the future steps an agent must be valid on to be labelled at all."""
    position_smoothing_s: float = 0.5
    """Moving-average window over positions before differencing (s)."""
    speed_smoothing_s: float = 0.5
    """Moving-average window over speeds (s)."""
    accel_smoothing_s: float = 0.9
    """Moving-average window over accelerations (s)."""
    static_speed: float = 0.5
    """A vehicle at or below this speed is stopped (m/s)."""
    slow_speed: float = 3.0
    """A moving vehicle at or below this speed moves slowly (m/s)."""
    vru_static_speed: float = 0.4
    """A pedestrian or cyclist at or below this speed is static (m/s)."""
    accel_threshold: float = 0.4
    """Acceleration at or beyond which a vehicle speeds up / slows down; below it, constant speed (m/s^2)."""
    min_speed_change: float = 1.0
    """Least speed change over a speeding-up or slowing-down span (m/s); smaller changes count as constant."""
    min_duration_s: float = 1.0
    """Shortest span of a speed, static, moving, crossing-street or walking-along label (s)."""
    slow_min_duration_s: float = 2.0
    """Shortest span of `moving_slowly` (s)."""
    parked_max_displacement: float = 1.0
    """A parked vehicle moves at most this far over all its valid steps, history included (m)."""
    parked_min_lane_offset: float = 1.5
    """A static vehicle this far or farther from the nearest lane centre is at the road side (m)."""
    parked_max_edge_distance: float = 1.5
    """A static vehicle whose centre is this close to a road edge is at the kerb (m)."""
    parked_queue_distance: float = 30.0
    """A static vehicle on a lane centre at most this far before a junction along its lane is queued, not parked
    (m; needs lane connectivity)."""
    turn_min_angle: float = math.radians(40.0)
    """Net heading change over the moving future that makes a turn (rad); positive is left. A turn at a skewed
    junction can change the heading by only about 45 degrees, and a window may not hold all of it."""
    straight_max_angle: float = math.radians(35.0)
    """Largest net heading change of a vehicle going straight (rad): roads that meet at an angle, or bend
    near a junction, make a through movement turn by up to about 35 degrees."""
    turn_span_fraction: float = 0.15
    """A turn's span runs from this fraction of its heading change to one minus it."""
    min_path_length: float = 5.0
    """Shortest future path of a vehicle given a turn / straight label (m)."""
    lane_match_radius: float = 3.0
    """Largest distance from a vehicle to the centerline of its matched lane (m)."""
    lane_match_max_heading: float = math.radians(45.0)
    """Largest heading disagreement between a vehicle and its matched lane (rad)."""
    off_road_distance: float = 4.0
    """A vehicle farther than this from every drivable lane centerline is off the main roads (m)."""
    junction_min_duration_s: float = 0.5
    """Shortest stay on junction lanes that counts, and longest gap bridged inside one (s)."""
    approach_lookahead: float = 40.0
    """A vehicle within this distance of a junction ahead (along its lanes or its path) approaches it (m)."""
    lane_min_run_s: float = 0.5
    """A matched lane must hold this long to count; shorter flickers join the lane before (s)."""
    lane_change_min_lateral: float = 2.0
    """Least lateral displacement, across the lane, that confirms a lane change (m)."""
    lane_change_settle_offset: float = 0.5
    """A lane change ends where the vehicle is first within this of its new lane centre (m)."""
    lane_change_start_offset: float = 0.2
    """A lane change starts at the last step where the vehicle is within this of its least offset toward the
    new lane over the `lane_change_max_duration_s` before the switch (that least offset counted as between
    the lane centre and `lane_change_settle_offset`): where its sideways motion begins, before its heading
    turns (m)."""
    lane_change_max_duration_s: float = 5.0
    """How far before the switch a lane change's start is looked for (s)."""
    lane_change_require_settled: bool = True
    """Leave out a lane change still under way at the agent's last step: not yet within
    `lane_change_settle_offset` of the new lane's centre and still moving toward it by more than
    `lane_change_start_offset` over the last `lane_change_settle_s` (the manoeuvre must end in the scene)."""
    lane_change_settle_s: float = 1.0
    """See `lane_change_require_settled` (s)."""
    pull_over_min_stop_s: float = 2.0
    """Shortest stop (at or below `static_speed`) that ends a pull-over (s)."""
    pull_over_lookback_s: float = 8.0
    """How far before the stop (and no earlier than the current step or the end of an earlier stop) the sideways
    motion of a pull-over is looked for (s)."""
    pull_over_min_lateral: float = 0.5
    """Least sideways displacement toward the road side, across the lane, before or during a stop that makes a
    pull-over (m; SUMO's pull-overs to the kerb of a 3.2 m lane move 0.6 m)."""
    pull_over_min_lane_offset: float = 0.4
    """Least offset of a pulled-over vehicle's stop from its lane's centre, toward the road side: it stops at the
    edge of its lane or beyond it, not on the centre as in a queue (m)."""
    pull_over_max_edge_distance: float = 3.0
    """Largest distance from a pulled-over vehicle's centre to a road edge where the map has road edges (m; a
    bike lane or a parking strip may lie between the kerb and the road edge)."""
    pull_over_junction_distance: float = 15.0
    """A stop on a junction lane or at most this far before one along its lane is a stop at the junction, not a
    pull-over (m; needs lane connectivity)."""
    pull_over_start_offset: float = 0.2
    """A pull-over starts at the last step within this of the vehicle's offset farthest from the road side before
    its stop: where its sideways motion begins (m)."""
    lane_position_max_offset: float = 1.5
    """Largest distance from the lane centre at which a vehicle gets a lane position (m)."""
    crossing_lane_radius: float = 2.0
    """A pedestrian or cyclist this close to a lane centerline, moving across it, crosses the street (m)."""
    crossing_min_angle: float = math.radians(50.0)
    """Least angle between VRU motion and the lane to count as crossing it (rad, folded to [0, pi/2])."""
    along_road_distance: float = 7.0
    """A VRU within this distance of a lane centerline is by the road (m)."""
    along_max_angle: float = math.radians(30.0)
    """Largest angle between VRU motion and the nearest lane to count as walking along it (rad, folded)."""
    infer_neighbors: bool = False
    """Infer lane neighbours from geometry when the map has none (otherwise lane positions are undecided)."""

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if not isinstance(value, bool) and not value >= 0:
                raise ValueError(f"HeuristicConfig.{f.name} must be >= 0, got {value!r}")
        if not 0 < self.min_future_fraction <= 1:
            raise ValueError(f"HeuristicConfig.min_future_fraction must be in (0, 1], got {self.min_future_fraction}")


# ---------------------------------------------------------------------------------------------- kinematics


@dataclass(frozen=True, eq=False)
class Kinematics:
    """Motion of every agent over all steps, from positions: gaps filled linearly, then smoothed."""

    xy: np.ndarray  # float64 [A, T, 2], smoothed; meaningful where `span`
    span: np.ndarray  # bool [A, T], from the first to the last valid step of the agent
    speed: np.ndarray  # float64 [A, T]
    accel: np.ndarray  # float64 [A, T], derivative of the smoothed speed
    course: np.ndarray  # float64 [A, T], direction of motion
    yaw: np.ndarray  # float64 [A, T], box heading, unwrapped and gap-filled
    dt: float  # median step (s)

    @classmethod
    def compute(cls, scenario: Scenario, config: HeuristicConfig) -> Kinematics:
        """Kinematics of every agent of `scenario`."""
        agents = scenario.agents
        times = scenario.timestamps
        dt = float(np.median(np.diff(times))) if len(times) > 1 else 0.1
        xy, yaw, span = _fill_gaps(agents.xy.astype(np.float64), agents.heading.astype(np.float64), agents.valid)
        xy = _smooth(xy, span, _steps(config.position_smoothing_s, dt))
        step_dt = np.maximum(np.diff(times), 1e-6) if len(times) > 1 else np.ones(0)
        velocity = _derivative(xy, span, step_dt)
        speed = _smooth(np.linalg.norm(velocity, axis=-1), span, _steps(config.speed_smoothing_s, dt))
        accel = _smooth(_derivative(speed, span, step_dt), span, _steps(config.accel_smoothing_s, dt))
        course = np.arctan2(velocity[..., 1], velocity[..., 0])
        return cls(xy, span, speed, accel, course, _smooth(yaw, span, _steps(config.position_smoothing_s, dt)), dt)


def _steps(seconds: float, dt: float) -> int:
    return max(1, round(seconds / dt))


def _fill_gaps(xy: np.ndarray, yaw: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Positions and unwrapped yaw interpolated linearly across invalid steps inside each agent's valid span."""
    num_agents, num_steps = valid.shape
    span = np.zeros_like(valid)
    xy_out = np.zeros_like(xy)
    yaw_out = np.zeros_like(yaw)
    steps = np.arange(num_steps)
    for a in range(num_agents):
        idx = np.flatnonzero(valid[a])
        if len(idx) == 0:
            continue
        span[a, idx[0] : idx[-1] + 1] = True
        for c in range(2):
            xy_out[a, :, c] = np.interp(steps, idx, xy[a, idx, c])
        yaw_out[a] = np.interp(steps, idx, np.unwrap(yaw[a, idx]))
    return xy_out, yaw_out, span


def _smooth(values: np.ndarray, span: np.ndarray, window: int) -> np.ndarray:
    """Centred moving average over axis 1 inside each agent's (contiguous) span; the window shrinks
    symmetrically near the span's ends, so a linear motion is left unbiased there."""
    if window <= 1 or values.shape[1] == 0:
        return values
    num_steps = values.shape[1]
    steps = np.arange(num_steps)
    first = np.argmax(span, axis=1)[:, None]
    last = (num_steps - 1 - np.argmax(span[:, ::-1], axis=1))[:, None]
    half = np.clip(np.minimum(np.minimum(steps - first, last - steps), window // 2), 0, None)
    lo, hi = steps - half, steps + half + 1
    extra = (1,) * (values.ndim - 2)
    padded = np.concatenate([np.zeros_like(values[:, :1]), np.cumsum(values, axis=1)], axis=1)
    total = np.take_along_axis(padded, hi.reshape(hi.shape + extra), 1) - np.take_along_axis(
        padded, lo.reshape(lo.shape + extra), 1
    )
    smooth = total / (hi - lo).reshape(hi.shape + extra)
    return np.where(span.reshape(span.shape + extra), smooth, values)


def _derivative(values: np.ndarray, span: np.ndarray, step_dt: np.ndarray) -> np.ndarray:
    """Time derivative over axis 1: the mean of the differences on either side of each step inside `span`."""
    out = np.zeros_like(values)
    if values.shape[1] < 2:
        return out
    ok = (span[:, 1:] & span[:, :-1]).astype(np.float64)
    shape = ok.shape + (1,) * (values.ndim - 2)
    diff = np.diff(values, axis=1) / step_dt.reshape((1, -1) + (1,) * (values.ndim - 2)) * ok.reshape(shape)
    count = np.zeros(span.shape)
    out[:, 1:] += diff
    out[:, :-1] += diff
    count[:, 1:] += ok
    count[:, :-1] += ok
    return out / np.maximum(count, 1.0).reshape(count.shape + (1,) * (values.ndim - 2))


# ---------------------------------------------------------------------------------------------- runs

INVALID = -99
"""Class of a step outside the agent's valid span in a per-step class sequence."""


def absorb_short_runs(classes: np.ndarray, min_len: int) -> np.ndarray:
    """Runs shorter than `min_len` (not INVALID) take the class of the run before them (or after, at the start)."""
    out = classes.copy()
    spans = value_runs(out)
    for i, (value, start, end) in enumerate(spans):
        if value == INVALID or end - start >= min_len:
            continue
        before = out[start - 1] if start > 0 else INVALID
        after = spans[i + 1][0] if i + 1 < len(spans) else INVALID
        fill = before if before != INVALID else after
        if fill != INVALID:
            out[start:end] = fill
    return out


# ---------------------------------------------------------------------------------------------- context


@dataclass(frozen=True, eq=False)
class LabelContext:
    """What the rules share for one scene: config, map index, kinematics, and lane matches computed once."""

    scenario: Scenario
    config: HeuristicConfig
    map_index: MapIndex
    kin: Kinematics

    # ------------------------------------------------------------------ window and agents
    @property
    def current(self) -> int:
        return self.scenario.current_index

    @cached_property
    def future(self) -> np.ndarray:
        """bool [A, F]: future steps inside each agent's valid span."""
        return self.kin.span[:, self.current :]

    @cached_property
    def eligible(self) -> np.ndarray:
        """bool [A]: valid at the current step and over enough of the future."""
        valid = self.scenario.agents.valid
        fut = valid[:, self.current :]
        share = fut.mean(axis=1) if fut.shape[1] else np.zeros(len(valid))
        return valid[:, self.current] & (share >= self.config.min_future_fraction)

    def agents_of(self, *types: AgentType) -> np.ndarray:
        """Indices of eligible agents of `types`."""
        return np.flatnonzero(self.eligible & np.isin(self.scenario.agents.types, [int(t) for t in types]))

    def track_id(self, agent: int) -> int:
        return int(self.scenario.agents.ids[agent])

    def steps(self, seconds: float) -> int:
        """A duration in whole steps (at least one)."""
        return _steps(seconds, self.kin.dt)

    def label(self, agent: int, key: str, start: int, end: int, **params: str) -> AgentLabel:
        """A label of `agent` over future steps [start, end), converted to window steps."""
        return AgentLabel(self.track_id(agent), key, self.current + start, self.current + end, params)

    def undecided(self, agent: int, key: str, reason: str) -> Undecided:
        return Undecided(self.track_id(agent), key, reason)

    def fut(self, array: np.ndarray) -> np.ndarray:
        """The future steps of a per-step [A, T, ...] array."""
        return array[:, self.current :]

    # ------------------------------------------------------------------ motion
    @cached_property
    def moving(self) -> np.ndarray:
        """bool [A, F]: above the stopped speed of the agent's type, inside its span."""
        types = self.scenario.agents.types
        limit = np.where(
            np.isin(types, [int(AgentType.VEHICLE)]), self.config.static_speed, self.config.vru_static_speed
        )
        return self.future & (self.fut(self.kin.speed) > limit[:, None])

    @cached_property
    def path_length(self) -> np.ndarray:
        """float64 [A, F]: distance travelled from the current step up to each future step."""
        xy = self.fut(self.kin.xy)
        step = np.linalg.norm(np.diff(xy, axis=1), axis=-1) * (self.future[:, 1:] & self.future[:, :-1])
        return np.concatenate([np.zeros((len(xy), 1)), np.cumsum(step, axis=1)], axis=1)

    # ------------------------------------------------------------------ lane matches [A, F]
    def _match(
        self, agents: np.ndarray, use_heading: bool, radius: float, drivable_only: bool, history: bool = False
    ) -> LaneMatch:
        """Lane matches of `agents` at their future steps [A, F], or at all their steps [A, T] with `history`."""
        span = self.kin.span if history else self.future
        num_agents, num_steps = span.shape
        mask = np.zeros_like(span)
        mask[agents] = span[agents]
        xy = (self.kin.xy if history else self.fut(self.kin.xy))[mask]
        heading = (self.kin.yaw if history else self.fut(self.kin.yaw))[mask] if use_heading else None
        found = self.map_index.match_lanes(
            xy,
            heading,
            radius=radius,
            max_heading_diff=self.config.lane_match_max_heading,
            drivable_only=drivable_only,
        )
        grid = LaneMatch(
            np.full((num_agents, num_steps), -1, np.int64),
            *(np.full((num_agents, num_steps), fill) for fill in (np.inf, np.nan, np.nan, np.nan)),
        )
        for name in ("lane", "distance", "lateral", "station", "heading"):
            getattr(grid, name)[mask] = getattr(found, name)
        return grid

    @cached_property
    def vehicle_lanes_all(self) -> LaneMatch:
        """Heading-aware drivable-lane match of every eligible vehicle at each step of its span [A, T], history
        included (a lane change that begins before the current step is seen whole)."""
        return self._match(self.agents_of(AgentType.VEHICLE), True, self.config.lane_match_radius, True, True)

    @cached_property
    def vehicle_lanes(self) -> LaneMatch:
        """Heading-aware drivable-lane match of every eligible vehicle at each future step [A, F]."""
        every = self.vehicle_lanes_all
        return LaneMatch(*(getattr(every, f.name)[:, self.current :] for f in fields(LaneMatch)))

    @cached_property
    def nearest_road(self) -> LaneMatch:
        """Nearest drivable lane (any heading) of every eligible vehicle, within the off-road distance."""
        return self._match(self.agents_of(AgentType.VEHICLE), False, self.config.off_road_distance, True)

    @cached_property
    def junction_runs(self) -> dict[int, list[tuple[int, int]]]:
        """Future spans each eligible vehicle spends on junction lanes (short gaps bridged, short stays dropped)."""
        lanes = self.vehicle_lanes.lane
        if self.map_index.num_lanes:
            on = (lanes >= 0) & self.map_index.is_junction[np.maximum(lanes, 0)]
        else:
            on = np.zeros(lanes.shape, bool)
        n = self.steps(self.config.junction_min_duration_s)
        return {int(a): true_runs(on[a], n, n) for a in self.agents_of(AgentType.VEHICLE)}

    # ------------------------------------------------------------------ shared decisions
    @cached_property
    def parked(self) -> dict[int, tuple[bool | None, str]]:
        """Parked decision (True / False / None = undecided) and its reason, per eligible vehicle."""
        return {int(a): _parked_decision(self, int(a)) for a in self.agents_of(AgentType.VEHICLE)}

    @cached_property
    def lane_changes(self) -> dict[int, list[LaneChange]]:
        """Lane changes (confirmed by lateral displacement) per eligible vehicle; the side is geometric when
        the map has no neighbour lists."""
        if not self.map_index.has_lanes:
            return {}
        return {int(a): _lane_changes(self, int(a)) for a in self.agents_of(AgentType.VEHICLE)}

    @cached_property
    def vru_crossing(self) -> np.ndarray:
        """bool [A, F]: a moving VRU inside a crosswalk or moving across a nearby lane centerline."""
        out = np.zeros_like(self.future)
        mask = self.moving.copy()
        mask[~np.isin(np.arange(len(mask)), self.agents_of(AgentType.PEDESTRIAN, AgentType.CYCLIST))] = False
        xy = self.fut(self.kin.xy)[mask]
        course = self.fut(self.kin.course)[mask]
        cfg = self.config
        hit = self.map_index.in_crosswalk(xy)
        if self.map_index.has_lanes:
            hit |= self.map_index.lanes_crossing(
                xy, course, radius=cfg.crossing_lane_radius, min_angle=cfg.crossing_min_angle
            )
        out[mask] = hit
        return out


def _parked_decision(ctx: LabelContext, a: int) -> tuple[bool | None, str]:
    """Parked: stopped over every valid step (history included) and at the road side at the current step
    (`MapIndex.parked_decision` on the nearest drivable lane; see `ParkedRule`)."""
    cfg = ctx.config
    span = ctx.kin.span[a]
    xy = ctx.kin.xy[a, span]
    still = ctx.kin.speed[a, span].max(initial=0.0) <= cfg.static_speed
    if not still or np.linalg.norm(xy - xy[0], axis=1).max(initial=0.0) > cfg.parked_max_displacement:
        return False, "moves"
    road = ctx.nearest_road
    now = LaneMatch(*(getattr(road, f.name)[a, :1] for f in fields(LaneMatch)))
    # Unlike the detector's (any lane nearby at any step), a parked label also needs the kerb: a car stopped on a
    # lane centre is parked only beside a road edge and away from junction queues.
    return ctx.map_index.parked_decision(
        now,
        ctx.fut(ctx.kin.xy)[a, :1],
        lane_offset=cfg.parked_min_lane_offset,
        queue_distance=cfg.parked_queue_distance,
        kerb_distance=cfg.parked_max_edge_distance,
    )


def _lane_chains(index: MapIndex, spans: list[tuple[int, int, int]]) -> list[tuple[list[int], int, int]]:
    """Lane runs joined where the next lane continues the previous one (an exit lane): the lanes one after
    another along the road, so a lane split at a node is not mistaken for a change; (lanes, start, end)."""
    chains: list[tuple[list[int], int, int]] = []
    for lane, start, end in spans:
        if chains and lane >= 0 and chains[-1][0][-1] >= 0 and lane in index.exits[chains[-1][0][-1]]:
            chains[-1][0].append(lane)
            chains[-1] = (chains[-1][0], chains[-1][1], end)
        else:
            chains.append(([lane], start, end))
    return chains


def _lane_changes(ctx: LabelContext, a: int) -> list[LaneChange]:
    """Switches between stable lane runs to a neighbour lane, confirmed by the lateral displacement.

    Lanes are matched over the agent's whole span (history included) so that a change begun before the
    current step is seen whole; a change counts when its switch (the first step on the new lane) lies in the
    future, and its span is clipped to the future.

    The detector finds lane changes its own way (`detector.lane_changes`): it needs the switch step and the
    leaders around it and is tuned against SUMO's interactions, this one needs the manoeuvre's span and the lane
    positions left and entered and is tuned against SUMO's lane changes; both report a `LaneChange`."""
    cfg, index = ctx.config, ctx.map_index
    match = ctx.vehicle_lanes_all
    current = ctx.current
    seq = np.where(ctx.kin.span[a], match.lane[a], INVALID)
    seq = absorb_short_runs(seq, ctx.steps(cfg.lane_min_run_s))
    chains = _lane_chains(index, value_runs(seq))
    lookback = ctx.steps(cfg.lane_change_max_duration_s)
    out = []
    for (lanes_a, a0, a1), (lanes_b, b0, b1) in itertools.pairwise(chains):
        lane_a, lane_b = lanes_a[-1], lanes_b[0]
        if b0 < current or lane_a < 0 or lane_b < 0 or lane_a == lane_b:
            continue
        if index.is_junction[lane_a] or index.is_junction[lane_b]:
            continue  # choosing among junction lanes is turning, not changing lanes
        lat_a, lat_b = match.lateral[a, a0:a1], match.lateral[a, b0:b1]
        xy_switch = ctx.kin.xy[a, b0]
        if index.neighbor_source == "none":
            side = index.geometric_side(lane_a, lane_b, xy_switch)
        else:
            side = index.neighbor_side(lane_a, lane_b, xy_switch)
        if side is None or not (np.isfinite(lat_a).all() and np.isfinite(lat_b).all()):
            continue
        sign = 1.0 if side == "left" else -1.0
        # Start: the last step before the switch near the least offset toward the new lane over the lookback,
        # on the lanes before the switch that are not junction lanes (offsets there follow the turn's lanes).
        first = max(a0, b0 - lookback)
        while first < b0 - 1 and index.is_junction[max(int(match.lane[a, first]), 0)]:
            first += 1
        # Offsets from flickers into other lanes (absorbed into the runs) do not count.
        own_a = np.isin(match.lane[a, first:b0], lanes_a)
        near = sign * match.lateral[a, first:b0]
        baseline = float(np.clip(near[own_a].min(initial=0.0), 0.0, cfg.lane_change_settle_offset))
        settled_a = np.flatnonzero(own_a & (near <= baseline + cfg.lane_change_start_offset))
        start = first + int(settled_a[-1]) if len(settled_a) else first
        own_b = np.isin(match.lane[a, b0:b1], lanes_b)
        settled_b = np.flatnonzero(own_b & (sign * lat_b >= -cfg.lane_change_settle_offset))
        if not len(settled_b) and cfg.lane_change_require_settled and not ctx.kin.span[a, b1:].any():
            tail = sign * lat_b[-ctx.steps(cfg.lane_change_settle_s) :]
            if tail[-1] - tail[0] > cfg.lane_change_start_offset:
                continue  # still moving across at the agent's last step
        end = b0 + int(settled_b[0]) if len(settled_b) else b1 - 1
        _, lat_a_at_switch = index.project_to_lane(lane_a, xy_switch)
        between = float(lat_a_at_switch[0]) - float(match.lateral[a, b0])
        # Across the lanes: from the start to the farthest the vehicle gets into the new lane.
        deepest = sign * float((sign * lat_b)[own_b].max(initial=sign * match.lateral[a, end]))
        lateral = between + deepest - float(match.lateral[a, start])
        if sign * lateral < cfg.lane_change_min_lateral:
            continue
        merge = bool(index.is_ending[lane_a] or index.is_ending[lane_b])
        s_a = float(index.project_to_lane(lane_a, ctx.kin.xy[a, start])[0][0])
        s_b = float(index.project_to_lane(lane_b, ctx.kin.xy[a, end])[0][0])
        out.append(
            LaneChange(
                a,
                int(index.lane_ids[lane_a]),
                int(index.lane_ids[lane_b]),
                b0,
                max(start, current),
                end + 1,
                side,
                lateral,
                index.lane_position(lane_a, s_a, with_ending=merge),
                index.lane_position(lane_b, s_b, with_ending=merge),
            )
        )
    return out


def _lane_frame(index: MapIndex, lane: int, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Signed lateral offset (left positive), station and centerline heading of each point [N, 2] at the nearest
    segment of `lane`. The offset is measured from that segment's line, so a point past the lane's start (on the
    lane before a split) keeps its sideways offset instead of its distance to the lane's end point."""
    segs = index.lanes.segments_of(lane)
    rows = np.arange(len(xy))
    dist, _, station = index.lanes.project(np.repeat(xy, len(segs), axis=0), np.tile(segs, len(xy)))
    pick = dist.reshape(len(xy), len(segs)).argmin(axis=1)
    best = segs[pick]
    heading = index.lanes.heading[best]
    rel = xy - index.lanes.start[best]
    lateral = np.cos(heading) * rel[:, 1] - np.sin(heading) * rel[:, 0]
    return lateral, station.reshape(len(xy), len(segs))[rows, pick], heading


def _nearest_edge_point(index: MapIndex, xy: np.ndarray, radius: float) -> np.ndarray | None:
    """The point [2] of the road edges nearest to `xy` [2], or None when none lies within `radius`."""
    point = np.asarray(xy, np.float64).reshape(1, 2)
    query, seg = index.edges.candidates(point, radius)
    if not len(seg):
        return None
    dist, _, _ = index.edges.project(point[query], seg)
    if dist.min() > radius:
        return None
    best = int(seg[np.argmin(dist)])
    start, end = index.edges.start[best], index.edges.end[best]
    along = end - start
    t = float(np.clip(np.dot(point[0] - start, along) / max(float(np.dot(along, along)), 1e-12), 0.0, 1.0))
    return start + t * along


def _pull_over_start(ctx: LabelContext, a: int, floor: int, stop: int) -> int | str | None:
    """The future step where vehicle `a`'s pull-over into the stop beginning at future step `stop` starts, a reason
    why it cannot be decided, or None when the stop is not a pull-over (see `PullingOverRule`). Sideways motion is
    looked for over future steps from `floor` on (the end of an earlier stop)."""
    cfg, index = ctx.config, ctx.map_index
    first = max(floor, stop - ctx.steps(cfg.pull_over_lookback_s))
    lanes = ctx.vehicle_lanes.lane[a, first : stop + 1]
    matched = np.flatnonzero(lanes >= 0)
    if not len(matched):
        return None  # off every lane all along: off the main roads, not pulling over from a lane
    lane = int(lanes[matched[-1]])  # the lane it drove in last: sideways motion is measured across it
    if index.is_junction[lane]:
        return None  # stopped in a junction
    xy = ctx.fut(ctx.kin.xy)[a, first : stop + 1]
    lateral, station, heading = _lane_frame(index, lane, xy)
    # Only the steps since the vehicle last turned away from that lane or drove on a junction lane count: offsets
    # from another road (before a turn) say nothing about moving sideways on this one.
    aligned = np.abs(wrap_angle(ctx.fut(ctx.kin.yaw)[a, first : stop + 1] - heading)) <= cfg.lane_match_max_heading
    on_junction = (lanes >= 0) & index.is_junction[np.maximum(lanes, 0)]
    broken = np.flatnonzero(~aligned | on_junction | ~ctx.future[a, first : stop + 1])
    begin = int(broken[-1]) + 1 if len(broken) else 0
    if begin >= len(xy) - 1:
        return None
    lat = lateral[begin:]
    to_right, to_left = float(lat.max() - lat[-1]), float(lat[-1] - lat.min())
    side = -1.0 if to_right >= to_left else 1.0  # toward the road side: right (-1) or left (+1) of the lane
    shift = max(to_right, to_left)
    if shift < cfg.pull_over_min_lateral or side * float(lat[-1]) < cfg.pull_over_min_lane_offset:
        return None  # no sideways move, or back on (or short of) a lane centre: a lane change, a queue
    if index.distance_to_junction(lane, float(station[-1])) <= cfg.pull_over_junction_distance:
        return None  # stopped at a junction
    if index.has_road_edges:
        kerb = _nearest_edge_point(index, xy[-1], cfg.pull_over_max_edge_distance)
        if kerb is None:
            return None  # not at the kerb
        if side * (float(_lane_frame(index, lane, kerb[None])[0][0]) - float(lat[-1])) < 0.0:
            return None  # the nearest edge lies on the other side: it moved away from the kerb (to the median)
    else:
        position = index.lane_position(lane, float(station[-1]))
        if position == "unknown":
            return "the map has no road edges and no lane neighbour lists to tell the road side"
        if position not in ("single", "rightmost" if side < 0 else "leftmost"):
            return None  # another lane lies on that side: not the road side
    toward = side * lat
    settled = np.flatnonzero(toward <= toward.min() + cfg.pull_over_start_offset)
    return first + begin + int(settled[-1])


# ---------------------------------------------------------------------------------------------- rules

Output = Iterator[AgentLabel | Undecided]


class LabelRule(ABC):
    """One heuristic label (or a small family of them): `apply` yields labels and undecided labels."""

    name: ClassVar[str]
    keys: ClassVar[tuple[str, ...]]

    @abstractmethod
    def apply(self, ctx: LabelContext) -> Output:
        """Labels and undecided labels of every eligible agent of the scene in `ctx`."""


LABEL_RULES: Registry[LabelRule] = Registry("heuristic label rule")
"""Every heuristic rule, by name; `label_agents` runs them in registration order."""


@LABEL_RULES.register
class SpeedProfileRule(LabelRule):
    """Vehicles: static / speeding_up / slowing_down / constant_speed spans from the smoothed speed and
    acceleration; spans shorter than `min_duration_s` join the span before, and a speed-up or slow-down
    that changes the speed by less than `min_speed_change` counts as constant speed."""

    name = "speed_profile"
    keys = ("static", "speeding_up", "slowing_down", "constant_speed")
    STOP, DOWN, CONST, UP = 0, 1, 2, 3

    def apply(self, ctx: LabelContext) -> Output:
        cfg = ctx.config
        speed, accel = ctx.fut(ctx.kin.speed), ctx.fut(ctx.kin.accel)
        min_len = ctx.steps(cfg.min_duration_s)
        for a in ctx.agents_of(AgentType.VEHICLE):
            classes = np.select(
                [speed[a] <= cfg.static_speed, accel[a] >= cfg.accel_threshold, accel[a] <= -cfg.accel_threshold],
                [self.STOP, self.UP, self.DOWN],
                self.CONST,
            )
            classes = absorb_short_runs(np.where(ctx.future[a], classes, INVALID), min_len)
            for value, start, end in value_runs(classes):
                change = speed[a, end - 1] - speed[a, start]
                if (value == self.UP and change < cfg.min_speed_change) or (
                    value == self.DOWN and -change < cfg.min_speed_change
                ):
                    classes[start:end] = self.CONST
            for value, start, end in value_runs(classes):
                if value != INVALID and end - start >= min_len:
                    key = {self.STOP: "static", self.UP: "speeding_up", self.DOWN: "slowing_down"}.get(
                        value, "constant_speed"
                    )
                    yield ctx.label(a, key, start, end)


@LABEL_RULES.register
class MovingSlowlyRule(LabelRule):
    """Vehicles: moving_slowly over spans of at least `slow_min_duration_s` between `static_speed` and
    `slow_speed`."""

    name = "moving_slowly"
    keys = ("moving_slowly",)

    def apply(self, ctx: LabelContext) -> Output:
        speed = ctx.fut(ctx.kin.speed)
        slow = ctx.moving & (speed <= ctx.config.slow_speed)
        min_len = ctx.steps(ctx.config.slow_min_duration_s)
        for a in ctx.agents_of(AgentType.VEHICLE):
            for start, end in true_runs(slow[a], min_len, ctx.steps(0.3)):
                yield ctx.label(a, "moving_slowly", start, end)


@LABEL_RULES.register
class ParkedRule(LabelRule):
    """Vehicles: parked when stopped over all valid steps (history included, moving at most
    `parked_max_displacement`) and at the road side: off every drivable lane, or at least
    `parked_min_lane_offset` from the nearest lane centre, or (not in a junction lane, nor within
    `parked_queue_distance` before one, where it would be queued) within `parked_max_edge_distance` of a road
    edge. A vehicle stopped on a lane centre where the map has no road edges is undecided (queue or kerb cannot
    be told apart); so is any stopped vehicle on a map without lanes."""

    name = "parked"
    keys = ("parked",)

    def apply(self, ctx: LabelContext) -> Output:
        for a, (decision, reason) in ctx.parked.items():
            if decision is None:
                yield ctx.undecided(a, "parked", reason)
            elif decision:
                span = np.flatnonzero(ctx.future[a])
                yield ctx.label(a, "parked", int(span[0]), int(span[-1]) + 1)


@LABEL_RULES.register
class OffMainRoadRule(LabelRule):
    """Vehicles: off_main_road over spans of at least `min_duration_s` farther than `off_road_distance` from
    every drivable lane centerline; undecided when the map has no lanes."""

    name = "off_main_road"
    keys = ("off_main_road",)

    def apply(self, ctx: LabelContext) -> Output:
        vehicles = ctx.agents_of(AgentType.VEHICLE)
        if not ctx.map_index.is_drivable.any():
            for a in vehicles:
                yield ctx.undecided(a, "off_main_road", "the map has no drivable lanes")
            return
        off = ctx.future & ~ctx.nearest_road.matched
        min_len = ctx.steps(ctx.config.min_duration_s)
        for a in vehicles:
            for start, end in true_runs(off[a], min_len):
                yield ctx.label(a, "off_main_road", start, end)


@LABEL_RULES.register
class TurnRule(LabelRule):
    """Vehicles that travel at least `min_path_length`: turning_left / turning_right when the net heading
    change between the first and last moving future steps is at least `turn_min_angle` (span: where the
    heading covers the middle of that change), going_straight when it is at most `straight_max_angle`
    (span: the moving steps); bends in between get neither."""

    name = "turn"
    keys = ("turning_left", "turning_right", "going_straight")

    def apply(self, ctx: LabelContext) -> Output:
        cfg = ctx.config
        yaw = ctx.fut(ctx.kin.yaw)
        for a in ctx.agents_of(AgentType.VEHICLE):
            moving = np.flatnonzero(ctx.moving[a])
            if len(moving) < 2 or ctx.path_length[a, moving[-1]] < cfg.min_path_length:
                continue
            first, last = int(moving[0]), int(moving[-1])
            heading = yaw[a, first : last + 1] - yaw[a, first]
            net = float(heading[-1])
            if abs(net) <= cfg.straight_max_angle:
                yield ctx.label(a, "going_straight", first, last + 1)
            elif abs(net) >= cfg.turn_min_angle:
                progress = heading / net
                start = first + int(np.argmax(progress >= cfg.turn_span_fraction))
                end = first + int(np.argmax(progress >= 1.0 - cfg.turn_span_fraction)) + 1
                yield ctx.label(a, "turning_left" if net > 0 else "turning_right", start, max(end, start + 1))


@LABEL_RULES.register
class CrossingIntersectionRule(LabelRule):
    """Vehicles: crossing_intersection over each stay on junction lanes (see `MapIndex`) of at least
    `junction_min_duration_s` during which the vehicle moves; undecided for moving vehicles on a map
    without lanes."""

    name = "crossing_intersection"
    keys = ("crossing_intersection",)

    def apply(self, ctx: LabelContext) -> Output:
        for a in ctx.agents_of(AgentType.VEHICLE):
            if not ctx.map_index.has_lanes:
                if ctx.moving[a].any():
                    yield ctx.undecided(a, "crossing_intersection", "the map has no lanes")
                continue
            for start, end in ctx.junction_runs[int(a)]:
                if ctx.moving[a, start:end].any():
                    yield ctx.label(a, "crossing_intersection", start, end)


@LABEL_RULES.register
class ApproachingIntersectionRule(LabelRule):
    """Vehicles on a non-junction lane at the current step (and not parked): approaching_intersection when
    their future path enters a junction lane within `approach_lookahead` metres (span: until it enters), or
    else when the lane graph reaches a junction lane within that distance ahead (span: the whole future).
    Without lane connectivity, a vehicle whose path does not enter a junction is undecided (unless the map
    has no junction lanes at all)."""

    name = "approaching_intersection"
    keys = ("approaching_intersection",)

    def apply(self, ctx: LabelContext) -> Output:
        index, cfg = ctx.map_index, ctx.config
        match = ctx.vehicle_lanes
        for a in ctx.agents_of(AgentType.VEHICLE):
            if ctx.parked[int(a)][0]:
                continue
            if not index.has_lanes:
                yield ctx.undecided(a, "approaching_intersection", "the map has no lanes")
                continue
            lane = int(match.lane[a, 0])
            if lane < 0 or index.is_junction[lane]:
                continue
            entries = [s for s, _ in ctx.junction_runs[int(a)] if s > 0]
            if entries and ctx.path_length[a, entries[0]] <= cfg.approach_lookahead:
                yield ctx.label(a, "approaching_intersection", 0, entries[0])
            elif entries:
                continue
            elif not index.is_junction.any():
                continue  # the map has no junction to approach
            elif not index.has_connectivity:
                yield ctx.undecided(
                    a, "approaching_intersection", "the map has no lane connectivity (exit lanes) to look ahead"
                )
            elif index.distance_to_junction(lane, float(match.station[a, 0])) <= cfg.approach_lookahead:
                span = np.flatnonzero(ctx.future[a])
                yield ctx.label(a, "approaching_intersection", 0, int(span[-1]) + 1)


@LABEL_RULES.register
class LanePositionRule(LabelRule):
    """Vehicles within `lane_position_max_offset` of their matched lane's centre at the current step (not
    parked): lane_position among same-direction neighbours, from the current step until the vehicle changes
    lanes or enters a junction; undecided where the map has no neighbour lists or the lane is a junction
    lane."""

    name = "lane_position"
    keys = ("lane_position",)

    def apply(self, ctx: LabelContext) -> Output:
        index, match = ctx.map_index, ctx.vehicle_lanes
        for a in ctx.agents_of(AgentType.VEHICLE):
            if ctx.parked[int(a)][0]:
                continue
            if not index.has_lanes:
                yield ctx.undecided(a, "lane_position", "the map has no lanes")
                continue
            lane = int(match.lane[a, 0])
            if lane < 0 or abs(float(match.lateral[a, 0])) > ctx.config.lane_position_max_offset:
                continue
            position = index.lane_position(lane, float(match.station[a, 0]))
            if position == "unknown":
                reason = (
                    "the vehicle is on a junction lane, where lanes have no neighbours"
                    if index.is_junction[lane]
                    else "the map has no lane neighbour information"
                )
                yield ctx.undecided(a, "lane_position", reason)
                continue
            stops = [int(np.flatnonzero(ctx.future[a])[-1]) + 1]
            stops += [c.start - ctx.current for c in ctx.lane_changes.get(int(a), []) if c.start > ctx.current]
            stops += [s for s, _ in ctx.junction_runs[int(a)] if s > 0]
            yield ctx.label(a, "lane_position", 0, min(stops), position=position)


@LABEL_RULES.register
class ChangingLanesRule(LabelRule):
    """Vehicles: changing_lanes(from, to) where the matched lane switches (after absorbing flickers shorter
    than `lane_min_run_s`) to a left or right neighbour lane, not to an exit lane nor between junction
    lanes, and the lateral displacement across the lanes is at least `lane_change_min_lateral`; span: from
    where the sideways motion begins (`lane_change_start_offset`) to the first step near the new lane's centre.
    Lanes are matched over the history too, so a change begun before the current step counts when its switch
    lies in the future; a lane that goes on into its exit lane counts as one lane; a change still under way at
    the last step is left out (`lane_change_require_settled`). Undecided when the switch is
    seen between parallel lanes but the map has no neighbour lists (or a lane position is unknown)."""

    name = "changing_lanes"
    keys = ("changing_lanes",)

    def apply(self, ctx: LabelContext) -> Output:
        for a in ctx.agents_of(AgentType.VEHICLE):
            if not ctx.map_index.has_lanes:
                if ctx.moving[a].any():
                    yield ctx.undecided(a, "changing_lanes", "the map has no lanes")
                continue
            for change in ctx.lane_changes.get(int(a), []):
                if ctx.map_index.neighbor_source == "none":
                    yield ctx.undecided(
                        a,
                        "changing_lanes",
                        f"a {change.lateral:+.1f} m lateral move to a parallel lane on the {change.side} at window "
                        f"steps {change.start}-{change.end}; the map has no lane "
                        "neighbour information",
                    )
                elif "unknown" in (change.from_position, change.to_position):
                    yield ctx.undecided(a, "changing_lanes", f"lane change to the {change.side}: lane position unknown")
                else:
                    yield ctx.label(
                        a,
                        "changing_lanes",
                        change.start - ctx.current,
                        change.end - ctx.current,
                        **{"from": change.from_position, "to": change.to_position},
                    )


@LABEL_RULES.register
class PullingOverRule(LabelRule):
    """Vehicles: pulling_over when a vehicle that moves at the current step or later (after any earlier stop) comes
    to a stop of at least `pull_over_min_stop_s` at the road side, having moved sideways toward it within
    `pull_over_lookback_s` before the stop. Sideways motion is measured across the lane it drove in last (since it
    last turned or left a junction lane): at least `pull_over_min_lateral` toward one side, ending at least
    `pull_over_min_lane_offset` beyond the lane centre on that side (at the edge of its lane or beyond it). That
    side is the road side when the stop is within `pull_over_max_edge_distance` of a road edge the vehicle moved
    toward or, on a map without road edges, when no same-direction lane lies on that side (a rightmost lane for a
    move to the right, a leftmost one for a move to the left, or a single lane). A stop on a junction lane or
    within `pull_over_junction_distance` before one is a stop at the junction, not a pull-over; a stop on a lane
    centre (behind a leader, at a stop line, after a lane change) has no offset, and a parked vehicle never moves.
    Span: from where the sideways motion begins (`pull_over_start_offset`) to the end of the stop. Undecided
    when the map has no lanes, or neither road edges nor lane neighbour lists to tell the road side."""

    name = "pulling_over"
    keys = ("pulling_over",)

    def apply(self, ctx: LabelContext) -> Output:
        stopped = ctx.future & ~ctx.moving
        min_stop = ctx.steps(ctx.config.pull_over_min_stop_s)
        for a in ctx.agents_of(AgentType.VEHICLE):
            floor = 0
            for stop, end in true_runs(stopped[a], min_stop, ctx.steps(0.3)):
                if ctx.moving[a, floor:stop].any():
                    if not ctx.map_index.has_lanes:
                        yield ctx.undecided(a, "pulling_over", "the map has no lanes")
                        break
                    start = _pull_over_start(ctx, int(a), floor, stop)
                    if isinstance(start, str):
                        yield ctx.undecided(a, "pulling_over", start)
                    elif start is not None:
                        yield ctx.label(a, "pulling_over", start, end)
                floor = end


@LABEL_RULES.register
class VruMotionRule(LabelRule):
    """Pedestrians and cyclists: static / moving spans of at least `min_duration_s`, split at
    `vru_static_speed`."""

    name = "vru_motion"
    keys = ("static", "moving")

    def apply(self, ctx: LabelContext) -> Output:
        min_len = ctx.steps(ctx.config.min_duration_s)
        for a in ctx.agents_of(AgentType.PEDESTRIAN, AgentType.CYCLIST):
            classes = np.where(ctx.future[a], ctx.moving[a].astype(np.int64), INVALID)
            for value, start, end in value_runs(absorb_short_runs(classes, min_len)):
                if value != INVALID and end - start >= min_len:
                    yield ctx.label(a, "moving" if value else "static", start, end)


@LABEL_RULES.register
class CrossingStreetRule(LabelRule):
    """Pedestrians and cyclists: crossing_street over spans of at least `min_duration_s` where they move
    inside a crosswalk polygon or across a lane centerline within `crossing_lane_radius` at
    `crossing_min_angle` or more; undecided for moving VRUs when the map has neither lanes nor crosswalks."""

    name = "crossing_street"
    keys = ("crossing_street",)

    def apply(self, ctx: LabelContext) -> Output:
        index = ctx.map_index
        min_len = ctx.steps(ctx.config.min_duration_s)
        for a in ctx.agents_of(AgentType.PEDESTRIAN, AgentType.CYCLIST):
            if not (index.has_lanes or index.has_crosswalks):
                if ctx.moving[a].any():
                    yield ctx.undecided(a, "crossing_street", "the map has no lanes and no crosswalks")
                continue
            for start, end in true_runs(ctx.vru_crossing[a], min_len, ctx.steps(0.5)):
                yield ctx.label(a, "crossing_street", start, end)


@LABEL_RULES.register
class WalkingAlongRoadRule(LabelRule):
    """Pedestrians and cyclists: walking_along_road over spans of at least `min_duration_s` where they move,
    are not crossing, and the nearest lane centerline within `along_road_distance` runs within
    `along_max_angle` of their motion (either direction); undecided for moving VRUs on a map without lanes."""

    name = "walking_along_road"
    keys = ("walking_along_road",)

    def apply(self, ctx: LabelContext) -> Output:
        cfg, index = ctx.config, ctx.map_index
        vrus = ctx.agents_of(AgentType.PEDESTRIAN, AgentType.CYCLIST)
        if not index.has_lanes:
            for a in vrus:
                if ctx.moving[a].any():
                    yield ctx.undecided(a, "walking_along_road", "the map has no lanes")
            return
        mask = ctx.moving & ~ctx.vru_crossing
        mask[~np.isin(np.arange(len(mask)), vrus)] = False
        near = index.match_lanes(ctx.fut(ctx.kin.xy)[mask], radius=cfg.along_road_distance, drivable_only=False)
        diff = np.abs(wrap_angle(ctx.fut(ctx.kin.course)[mask] - near.heading))
        along = np.zeros_like(mask)
        along[mask] = near.matched & (np.minimum(diff, np.pi - diff) <= cfg.along_max_angle)
        min_len = ctx.steps(cfg.min_duration_s)
        for a in vrus:
            for start, end in true_runs(along[a], min_len, ctx.steps(0.5)):
                yield ctx.label(a, "walking_along_road", start, end)


# ---------------------------------------------------------------------------------------------- entry point


def label_agents(
    scenario: Scenario, config: HeuristicConfig | None = None, map_index: MapIndex | None = None
) -> tuple[tuple[AgentLabel, ...], tuple[Undecided, ...]]:
    """Heuristic single-agent labels of `scenario`'s future window, and the labels the map could not decide;
    each sorted by agent order, start step and key. `map_index` may be passed to reuse one across windows."""
    config = config or HeuristicConfig()
    if map_index is None:
        map_index = MapIndex.build(scenario.road_map, infer_neighbors=config.infer_neighbors)
    ctx = LabelContext(scenario, config, map_index, Kinematics.compute(scenario, config))
    labels: list[AgentLabel] = []
    undecided: dict[tuple[int, str], Undecided] = {}
    for name in LABEL_RULES.names():
        for item in LABEL_RULES.create(name).apply(ctx):
            if isinstance(item, Undecided):
                undecided.setdefault((item.track_id, item.key), item)
            else:
                labels.append(item)
    order = {int(t): i for i, t in enumerate(scenario.agents.ids)}
    labels.sort(key=lambda lab: (order[lab.track_id], lab.start, lab.key, lab.end))
    kept = sorted(undecided.values(), key=lambda u: (order[u.track_id], u.key))
    return tuple(labels), tuple(kept)
