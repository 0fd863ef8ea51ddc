"""One scene's map read for targets (`TargetContext`): where each agent is (`AgentHere`), its next junction and its
road ahead, computed once; and the pieces of geometry several behaviours' targets share (whether one agent leads
another in its lane, the lane beside, crossings of two ways, the stop points of signals, the time to cover a
distance). Read from the scene at the current step only. See docs/interdrive.md ('Targets and feasibility')."""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np

from langtraj.angles import wrap_angle
from langtraj.interdrive.behaviour import Behaviour, Side
from langtraj.interdrive.detector.config import DetectorConfig
from langtraj.interdrive.targets.config import CounterfactualConfig
from langtraj.interdrive.targets.lanes_ahead import (
    AgentOnLane,
    JunctionAhead,
    StationAhead,
    junction_ahead,
    stations_ahead,
)
from langtraj.interdrive.targets.target import BehaviourTarget, TargetUnavailable
from langtraj.polylines import arc_lengths, point_at, project_on_polyline, resample
from langtraj.roads import MapIndex
from langtraj.roads.position import current_speeds
from langtraj.roads.routes import ROUTE_SPACING, route, straight_line
from langtraj.scenario.model import FUTURE_STEPS, STEP_SECONDS, Scenario
from langtraj.scenario.types import RED_STATES, AgentType, StateField, TrafficLightState

JUDGE = DetectorConfig()
"""The judge's thresholds (`interdrive.detector`), which a target that must be judged to happen starts from."""
COMFORT_DECELERATION = 2.0
"""Comfortable braking (m/s^2): a stop lies where it brings the agent to rest, and a pull-over needs room to stop
this way before the next junction."""
SPEED_CHANGE = 3.0
"""Speed gained or lost by speeding up or slowing down (m/s; the labelers need at least 1 m/s)."""
HORIZON_S = FUTURE_STEPS * STEP_SECONDS
"""The simulated future the target must fit in (s)."""
LANE_CHANGE_S = 3.0
"""Time a lane change takes to settle in its new lane (s)."""
LANE_CHANGE_MIN_M = 15.0
"""Least length of the new lane before its next junction that a lane change needs (m)."""
CROSSING_RADIUS = 2.0
"""Two paths ahead cross where they come this close (m) at more than `CROSSING_ANGLE` (a target's conflict point,
on map paths, before anything is driven; the judge's yield rule is the detector's, on driven tracks)."""
CROSSING_ANGLE = math.radians(20.0)
GO_FIRST_ACCELERATION = 2.5
"""The most an agent asked to go first is assumed to speed up by (m/s^2), up to `GO_FIRST_TOP_SPEED`."""
GO_FIRST_TOP_SPEED = 15.0
GO_FIRST_MARGIN_S = 0.5
"""Going first must get the agent to the crossing this much earlier than the other agent at its speed (s)."""
RED_STOP_LATERAL = 1.5
"""How close to a way a signal's stop point must lie to be that way's (m; lanes are about 3.5 m apart)."""
FOLLOWER_RANGE_M = 40.0
"""How far (bumper to bumper, m) behind a braking lead, or ahead of a tailgater, the other agent may be."""
ON_ROUTE_M = 4.0
"""An agent with a known route (`TargetContext.routes`) drives it while its centre is within this (m) of it; farther
(it left its route), its way is read from the lanes as any agent's."""
NOT_GO_STATES = tuple(s for s in TrafficLightState if s.is_stop or s.is_caution)
"""Signal states that stop a lane or are about to: the other agent must face none of these before the crossing (it
has the right of way a red-light runner cuts)."""


# ---------------------------------------------------------------------------------------------- the agent


@dataclass(frozen=True)
class AgentHere:
    """An agent at the scene's current step as targets read it: its type, where it is on the lanes, its pose and
    size."""

    track_id: int
    kind: AgentType
    here: AgentOnLane
    xy: np.ndarray
    heading: float
    length: float
    width: float
    search: float
    """How far along the lane graph the map is searched (`CounterfactualConfig.reach`)."""

    @property
    def reach(self) -> float:
        """How far a path ahead is drawn (m): beyond what the horizon can cover."""
        return max(60.0, (self.here.speed + SPEED_CHANGE) * HORIZON_S + 20.0)

    @property
    def on_lane(self) -> bool:
        return self.here.lane >= 0


class TargetContext:
    """One scene's map read for targets: the map index, the settings and, per agent, where it is, the next junction's
    branches and its road ahead, each computed once, so that asking about every behaviour of an agent
    (`feasibility.behaviour_feasibility`) reads the map once (`derive.target_of` derives one target).

    `routes`: track id -> the route [P, 2] (world frame) an agent is known to drive: an ego under a planner drives the
    mission it is given (`roads.mission`), not whichever branch the straightest exits or the junction's list give, so
    a target toward it (a runner across its way, a pull-out timed to its arrival) reads that route as its one way
    ahead."""

    def __init__(
        self,
        scenario: Scenario,
        index: MapIndex,
        config: CounterfactualConfig | None = None,
        routes: Mapping[int, np.ndarray] | None = None,
    ):
        self.scenario, self.index, self.config = scenario, index, config or CounterfactualConfig()
        self.routes = dict(routes or {})
        self._on_route: dict[int, np.ndarray | None] = {}
        self._agents: dict[int, AgentHere | None] = {}
        self._junctions: dict[int, JunctionAhead] = {}
        self._stations: dict[int, list[StationAhead]] = {}

    def agent(self, track_id: int, behaviour: Behaviour) -> AgentHere:
        """Agent `track_id` at the current step; `TargetUnavailable` (undecided) when it is not valid there."""
        if track_id not in self._agents:
            self._agents[track_id] = self._read(track_id)
        found = self._agents[track_id]
        if found is None:
            raise TargetUnavailable(track_id, behaviour, "undecided", "it is not valid at the current step")
        return found

    def _read(self, track_id: int) -> AgentHere | None:
        row = self.scenario.agents.index_of(track_id)
        c = self.scenario.current_index
        if not self.scenario.agents.valid[row, c]:
            return None
        state = self.scenario.agents.states[row, c]
        cfg = self.config.heuristics
        here = AgentOnLane.of(
            self.scenario, row, self.index, radius=cfg.lane_match_radius, max_heading=cfg.lane_match_max_heading
        )
        return AgentHere(
            track_id,
            AgentType(int(self.scenario.agents.types[row])),
            here,
            state[[StateField.X, StateField.Y]].astype(np.float64),
            float(state[StateField.HEADING]),
            float(state[StateField.LENGTH]),
            float(state[StateField.WIDTH]),
            self.config.reach(here.speed),
        )

    def length(self, track_id: int) -> float:
        """Agent `track_id`'s length at the current step (m)."""
        agents = self.scenario.agents
        return float(agents.states[agents.index_of(track_id), self.scenario.current_index, StateField.LENGTH])

    def junction(self, agent: AgentHere) -> JunctionAhead:
        """The branches of the agent's next junction within its search (`lanes_ahead.junction_ahead`)."""
        if agent.track_id not in self._junctions:
            self._junctions[agent.track_id] = junction_ahead(self.index, agent.here, agent.search, self.config)
        return self._junctions[agent.track_id]

    def stations(self, agent: AgentHere) -> list[StationAhead]:
        """The stations of the agent's road ahead within its search (`lanes_ahead.stations_ahead`)."""
        if agent.track_id not in self._stations:
            self._stations[agent.track_id] = stations_ahead(self.index, agent.here, agent.search, self.config)
        return self._stations[agent.track_id]

    def moving(self, agent: AgentHere) -> bool:
        """Faster than the labelers' standing speed by their least speed change."""
        cfg = self.config.heuristics
        return agent.here.speed > cfg.static_speed + cfg.min_speed_change

    def need_lane(self, agent: AgentHere, behaviour: Behaviour, what: str) -> None:
        """Undecided when the map has no lanes or the agent is on none."""
        if not self.index.has_lanes:
            raise TargetUnavailable(agent.track_id, behaviour, "undecided", "the map has no lanes")
        if not agent.on_lane:
            reason = f"it is on no lane at the current step, so its {what} are unknown"
            raise TargetUnavailable(agent.track_id, behaviour, "undecided", reason)

    def ahead(self, agent: AgentHere) -> np.ndarray:
        """The agent's route from where it is, where it drives a known one (`routes`, within `ON_ROUTE_M`); else its
        lane ahead by the straightest exits, or, off lanes (a pedestrian, a cyclist, a map without lanes), the line
        along its heading."""
        if (known := self.on_route(agent)) is not None:
            return known
        if self.index.has_lanes and agent.on_lane:
            return route(self.index, [agent.here.lane], agent.here.station, agent.reach)
        return straight_line(agent.xy, agent.heading, max(20.0, agent.here.speed * HORIZON_S + 10.0))

    def on_route(self, agent: AgentHere) -> np.ndarray | None:
        """The agent's known route (`routes`) from its nearest point on, `agent.reach` m of it at least where the
        route has them; None where it has none or is more than `ON_ROUTE_M` off it. Found once per agent."""
        if agent.track_id not in self._on_route:
            self._on_route[agent.track_id] = self._read_route(agent)
        return self._on_route[agent.track_id]

    def _read_route(self, agent: AgentHere) -> np.ndarray | None:
        known = self.routes.get(agent.track_id)
        if known is None or len(known) < 2:
            return None
        found = project_on_polyline(agent.xy[None], known)
        if float(found.distance[0]) > ON_ROUTE_M:
            return None
        stations, start = arc_lengths(known), float(found.station[0])
        keep = (stations > start) & (stations <= start + max(agent.reach, ROUTE_SPACING))
        out = np.concatenate([point_at(known, start)[None], known[keep]])
        return out if len(out) >= 2 else None

    def ways_ahead(self, agent: AgentHere) -> list[np.ndarray]:
        """Every way the agent may go: its known route alone where it drives one (`on_route`); else its lane ahead
        first, then each branch of the next junction."""
        if (known := self.on_route(agent)) is not None:
            return [known]
        first = self.ahead(agent)
        if not (self.index.has_lanes and self.index.has_connectivity and agent.on_lane):
            return [first]
        return [first] + [
            route(self.index, branch.lanes, agent.here.station, max(agent.reach, branch.exit_at + 25.0))
            for branch in self.junction(agent).branches
        ]

    def standing_on(self, agent: AgentHere, path: np.ndarray, upto: float) -> int | None:
        """The track id of the nearest other agent standing (at most `STANDING_MPS`) on `path` ahead of `agent`,
        before station `upto` (`first_on`): a queue at a light that the agent cannot drive through; None where the
        way is clear."""
        found = self.first_on(agent, path, upto, most_mps=STANDING_MPS)
        return None if found is None else found[0]

    def first_on(
        self,
        agent: AgentHere,
        path: np.ndarray,
        upto: float,
        most_mps: float = math.inf,
        kind: AgentType | None = None,
    ) -> tuple[int, float, float] | None:
        """The nearest other agent (of `kind`, where given) on `path` ahead of `agent` before station `upto` (its
        centre within the two half widths and `STANDING_MARGIN_M` of the path), moving at most `most_mps`: its track
        id, how far ahead of the agent along the path (m, centre to centre) and its speed (m/s); None where there is
        none."""
        agents, c = self.scenario.agents, self.scenario.current_index
        states, valid = agents.states[:, c], agents.valid[:, c].copy()
        valid[agents.index_of(agent.track_id)] = False
        if kind is not None:
            valid &= agents.types == int(kind)
        speed = current_speeds(self.scenario)
        rows = np.flatnonzero(valid & (speed <= most_mps))
        if not len(rows) or len(path) < 2:
            return None
        found = project_on_polyline(states[rows][:, [StateField.X, StateField.Y]], path)
        mine = float(project_on_polyline(agent.xy[None], path).station[0])
        corridor = 0.5 * (agent.width + states[rows, StateField.WIDTH]) + STANDING_MARGIN_M
        ahead = found.station - mine
        on = (ahead > 0.0) & (found.station <= upto) & (found.distance <= corridor)
        if not on.any():
            return None
        k = int(np.argmin(np.where(on, ahead, np.inf)))
        return int(agents.ids[rows[k]]), float(ahead[k]), float(speed[rows[k]])


STANDING_MPS = 1.0
"""The most an agent moves (m/s) to count as standing in another's way (`TargetContext.standing_on`)."""
STANDING_MARGIN_M = 0.3
"""Beyond the two half widths, how near a path an agent's centre is to stand on it (m), as the IDM's corridor."""


# ---------------------------------------------------------------------------------------------- shared geometry


def gap_behind(index: MapIndex, lead: AgentHere, follower: AgentHere) -> float | None:
    """The bumper gap (m) from `follower`'s front to `lead`'s rear when `follower` is behind `lead` in its lane:
    heading its way (within 45 degrees), and on one of the pieces of its lane or within 2 m of its line; else None."""
    h = np.array([math.cos(lead.heading), math.sin(lead.heading)])
    d = lead.xy - follower.xy
    along, across = float(d @ h), abs(float(d @ np.array([-h[1], h[0]])))
    if along <= 0.0 or abs(wrap_angle(lead.heading - follower.heading)) > math.radians(45.0):
        return None
    same_lane = lead.on_lane and follower.on_lane and follower.here.lane in lane_pieces(index, lead.here.lane)
    if not (same_lane or across <= 2.0):
        return None
    return along - 0.5 * (lead.length + follower.length)


def pair_gap(
    ctx: TargetContext, agent: AgentHere, other: AgentHere, behaviour: Behaviour, lead: AgentHere, where: str
) -> float:
    """The bumper gap between the two when `lead` (one of them) leads the other in its lane within `FOLLOWER_RANGE_M`
    (`gap_behind`); else `TargetUnavailable` (infeasible) saying where `other` is not (`where`: "behind" it,
    "ahead of" it)."""
    follower = other if lead is agent else agent
    gap = gap_behind(ctx.index, lead, follower)
    if gap is None or gap > FOLLOWER_RANGE_M:
        why = f"not {where} it in its lane" if gap is None else f"{gap:.0f} m {where} it (at most {FOLLOWER_RANGE_M:g})"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", f"@{other.track_id} is {why}")
    return gap


def lane_beside(
    ctx: TargetContext, agent: AgentHere, other: AgentHere, behaviour: Behaviour, within: float
) -> tuple[Side, int, float]:
    """The other's lane where it lies beside the agent's (`MapIndex.neighbour_lane`, either side), at the agent or at
    a station of its road up to `within` m ahead: (side, lane, station on it beside the agent's). Undecided without
    lanes or neighbour data; infeasible where the other's lane is not beside its own."""
    index = ctx.index
    ctx.need_lane(agent, behaviour, "neighbour lanes")
    if not other.on_lane:
        raise TargetUnavailable(agent.track_id, behaviour, "undecided", f"@{other.track_id} is on no lane")
    if index.neighbor_source == "none":
        raise TargetUnavailable(agent.track_id, behaviour, "undecided", "the map has no lane neighbour information")
    ahead = [(agent.here.lane, agent.here.station)]
    ahead += [(p.lane, p.station) for p in ctx.stations(agent) if p.distance <= within]
    theirs = lane_pieces(index, other.here.lane)
    for lane, station in ahead:
        for side in ("left", "right"):
            beside = index.neighbour_lane(lane, station, side)  # type: ignore[arg-type]
            if beside is not None and beside[0] in theirs:
                return side, beside[0], beside[1]  # type: ignore[return-value]
    reason = f"@{other.track_id} is not in a lane beside its own"
    raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)


def lead_of(agent: AgentHere, other: AgentHere) -> float:
    """How far the agent's centre is ahead of the other's along the other's heading (m)."""
    heading = np.array([math.cos(other.heading), math.sin(other.heading)])
    return float((agent.xy - other.xy) @ heading)


def offset_of(agent: AgentHere, other: AgentHere) -> float:
    """How far the agent's centre is to the left of the other's heading line (m; negative: to its right)."""
    left = np.array([-math.sin(other.heading), math.cos(other.heading)])
    return float((agent.xy - other.xy) @ left)


def into_lane(index: MapIndex, agent: AgentHere, lane: int, station: float) -> np.ndarray:
    """The agent's way into `lane` at `station` (a lane change, a cut-in): a straight lead-in from where it is, then
    the lane on."""
    path = route(index, [lane], station, agent.reach)
    lead_in = resample(np.stack([agent.xy, path[0]]), ROUTE_SPACING)
    return np.concatenate([lead_in[:-1], path])


def stop_points(ctx: TargetContext, states: Iterable[TrafficLightState]) -> np.ndarray | None:
    """The stop points [K, 2] of the signals showing one of `states` at the current step (none: [0, 2]); None where
    the scene has no signals."""
    lights, c = ctx.scenario.traffic_lights, ctx.scenario.current_index
    if lights is None or lights.num_lanes == 0:
        return None
    showing = np.isin(lights.states[c], [int(s) for s in states]) & lights.valid[c]
    return np.asarray(lights.stop_points)[showing, :2]


def red_ahead(ctx: TargetContext, path: np.ndarray, station: float) -> float | None:
    """The station along `path` (m) of the first stop point of a signal showing stop at the current step that lies on
    it (within `RED_STOP_LATERAL`) before `station`; None where none does."""
    stops = stop_points(ctx, RED_STATES)
    if stops is None or not len(stops):
        return None
    found = project_on_polyline(stops, path)
    on = (found.distance < RED_STOP_LATERAL) & (found.station < station)
    return float(found.station[on].min()) if on.any() else None


def red_on_way(ctx: TargetContext, path: np.ndarray, station: float) -> bool:
    """Whether the stop point of a signal showing stop at the current step lies on `path` before `station`."""
    return red_ahead(ctx, path, station) is not None


def keeps_going(ctx: TargetContext, agent: AgentHere, other: AgentHere, behaviour: Behaviour, seconds: float) -> None:
    """Infeasible where a signal showing stop, or a pedestrian, lies on the other's way (`TargetContext.ahead`: its
    route, where it has one) within what it drives in `seconds` at its speed and then brakes over at
    `COMFORT_DECELERATION`: an other that stops there (a planner that keeps the law, or yields to a walker crossing)
    has stopped before a behaviour needing it to drive on for `seconds` (a cut-in settled in front of it, a tailgater
    on its tail) could happen."""
    v, way = other.here.speed, ctx.ahead(other)
    reach = v * seconds + v * v / (2.0 * COMFORT_DECELERATION)
    red = red_ahead(ctx, way, reach)
    walker = ctx.first_on(other, way, reach, kind=AgentType.PEDESTRIAN)
    if red is None and walker is None:
        return
    what = f"a red light {red:.0f} m" if red is not None else f"@{walker[0]} on foot {walker[1]:.0f} m"
    reason = f"{what} ahead on @{other.track_id}'s way: it stops there within the {seconds:.1f} s this needs it on"
    raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)


def red_before(stops: np.ndarray, ways: list[np.ndarray], point: np.ndarray) -> bool:
    """Whether every one of `ways` that passes `point` has one of `stops` (of signals that do not show go) on it
    before that point."""
    passing = [(w, project_on_polyline(point, w)) for w in ways]
    passing = [(w, float(at.station)) for w, at in passing if at.distance < CROSSING_RADIUS]
    if not passing:
        return False
    for way, at in passing:
        found = project_on_polyline(stops, way)
        if not ((found.distance < RED_STOP_LATERAL) & (found.station < at)).any():
            return False
    return True


def lane_pieces(index: MapIndex, lane: int, hops: int = 3) -> set[int]:
    """`lane` and the non-junction lanes up to `hops` before and after it: the pieces of one lane of a road."""
    found, frontier = {lane}, {lane}
    for _ in range(hops):
        frontier = {n for x in frontier for n in (*index.exits[x], *index.entries[x]) if not index.is_junction[n]}
        frontier -= found
        found |= frontier
    return found


def crossing(mine: np.ndarray, theirs: np.ndarray) -> tuple[int, float] | None:
    """The index of the first point of path `mine` within `CROSSING_RADIUS` of path `theirs` at more than
    `CROSSING_ANGLE` to it, and the other's distance along `theirs` to there; None when they do not cross."""
    if len(mine) < 2 or len(theirs) < 2:
        return None
    gaps = np.linalg.norm(mine[:, None] - theirs[None], axis=-1)
    hm = np.arctan2(*np.gradient(mine, axis=0).T[::-1])
    ht = np.arctan2(*np.gradient(theirs, axis=0).T[::-1])
    crossing = (gaps < CROSSING_RADIUS) & (np.abs(wrap_angle(hm[:, None] - ht[None, :])) > CROSSING_ANGLE)
    rows = np.flatnonzero(crossing.any(axis=1))
    if not rows.size:
        return None
    i = int(rows[0])
    j = int(np.argmin(np.where(crossing[i], gaps[i], np.inf)))
    return i, float(arc_lengths(theirs)[j])


def order_target(ctx: TargetContext, agent: AgentHere, other: AgentHere, behaviour: Behaviour) -> BehaviourTarget:
    """Going first or yielding: the first point of the agent's ways ahead (`TargetContext.ways_ahead`) that a way of the
    other agent crosses, and when the other gets there at its current speed: the agent's first way that any of the
    other's crosses is taken, with its earliest crossing. Yielding is always possible (it can wait; without a
    crossing its target slows it); going first is infeasible when a pedestrian or cyclist other is already within
    3 m of the crossing (it is crossing) or gets there before the agent can even speeding up at
    `GO_FIRST_ACCELERATION`, and undecided without a crossing."""
    ways = ctx.ways_ahead(agent)
    mine = ways[0]
    conflict, eta, reason = None, None, f"no crossing of its way with @{other.track_id}'s ahead"
    theirs = ctx.ways_ahead(other)
    for path in ways:
        crossings = [c for c in (crossing(path, t) for t in theirs) if c is not None]
        if crossings:
            i, distance = min(crossings)
            mine, conflict = path, path[i]
            eta = distance / max(other.here.speed, 1.0)
            order = "before" if behaviour is Behaviour.GO_FIRST else "after"
            reason = f"it passes the conflict point {arc_lengths(path)[i]:.0f} m ahead {order} @{other.track_id}"
            break
    station = None if conflict is None else float(project_on_polyline(conflict, mine).station)
    target = BehaviourTarget(
        agent.track_id,
        behaviour,
        mine,
        reason,
        station_of_goal=station,
        other_id=other.track_id,
        conflict=conflict,
        other_eta=eta,
        current_speed=agent.here.speed,
        other_speed=other.here.speed,
    )
    if behaviour is Behaviour.GO_FIRST:
        check_going_first(agent, other, target)
    return target


def check_going_first(agent: AgentHere, other: AgentHere, target: BehaviourTarget) -> None:
    """Raise where the agent cannot get to the crossing first (see `order_target`)."""
    if target.conflict is None or target.station_of_goal is None or target.other_eta is None:
        raise TargetUnavailable(agent.track_id, target.behaviour, "undecided", target.reason)
    if other.kind != AgentType.VEHICLE and np.linalg.norm(other.xy - target.conflict) < 3.0:
        reason = f"@{other.track_id} is already crossing its path"
        raise TargetUnavailable(agent.track_id, target.behaviour, "infeasible", reason)
    need = time_to_cover(target.station_of_goal, target.current_speed)
    if need + GO_FIRST_MARGIN_S >= target.other_eta:
        reason = f"@{other.track_id} gets to the crossing in {target.other_eta:.1f} s; it needs {need:.1f} s"
        raise TargetUnavailable(agent.track_id, target.behaviour, "infeasible", reason)


def time_to_cover(distance: float, speed: float) -> float:
    """Seconds to cover `distance` m from `speed`, speeding up at `GO_FIRST_ACCELERATION` to the top speed."""
    a, top = GO_FIRST_ACCELERATION, max(GO_FIRST_TOP_SPEED, speed)
    ramp = (top - speed) / a
    ramp_distance = speed * ramp + 0.5 * a * ramp**2
    if distance <= ramp_distance:
        return (-speed + math.sqrt(speed**2 + 2 * a * distance)) / a
    return ramp + (distance - ramp_distance) / top
