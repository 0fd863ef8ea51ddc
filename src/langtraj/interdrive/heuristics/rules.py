"""The heuristic label rules: one `LabelRule` per label (or small family), registered in `LABEL_RULES`
(docs/interdrive.md, 'Single-agent labels')."""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Iterator
from typing import ClassVar

import numpy as np

from langtraj.angles import wrap_angle
from langtraj.interdrive.heuristics.context import LabelContext
from langtraj.interdrive.heuristics.pull_over import _pull_over_start
from langtraj.interdrive.heuristics.runs import INVALID, absorb_short_runs
from langtraj.interdrive.labels import AgentLabel, Undecided
from langtraj.registry import Registry
from langtraj.runs import true_runs, value_runs
from langtraj.scenario.types import AgentType

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
