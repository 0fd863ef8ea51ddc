"""`LabelContext`: what the heuristic rules share for one scene (window, eligible agents, lane matches, parked
vehicles, lane changes), each computed once (docs/interdrive.md, 'Single-agent labels')."""

from __future__ import annotations

import itertools
from dataclasses import dataclass, fields
from functools import cached_property

import numpy as np

from langtraj.interdrive.heuristics.config import HeuristicConfig
from langtraj.interdrive.heuristics.kinematics import Kinematics, _steps
from langtraj.interdrive.heuristics.runs import INVALID, absorb_short_runs
from langtraj.interdrive.labels import AgentLabel, Undecided
from langtraj.roads import LaneChange, LaneMatch, MapIndex
from langtraj.runs import true_runs, value_runs
from langtraj.scenario.model import Scenario
from langtraj.scenario.types import AgentType


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
