"""Targets from the map: where a behaviour asked of an agent takes it, derived from the scene at the current step.

A prompt names a behaviour kind (`interdrive.behaviour`); guidance and candidate selection need something concrete
to steer toward. `derive_target` reads the agent's lane and the lane graph (as `counterfactual` does to decide
feasibility) and returns a `BehaviourTarget` in world coordinates:

- a turn or going straight: the lanes of the named branch of the next junction, from the agent to past its exit;
- a lane change: the neighbour lane's centreline on that side, from a little ahead of the agent;
- a stop: the agent's lane ahead and a stop station that comfortable braking reaches (a stop line or crosswalk
  when one lies a little beyond);
- pulling over: the lane ahead shifted toward the kerb on the right, and a stop station;
- speeding up or slowing down: the lane ahead and a target speed;
- going first or yielding: both agents' lanes ahead, the conflict point where they cross, and the order;
- following: the other agent's lane ahead.

Only the current step and the past are read (never the logged future), so a simulation may use the target.
See docs/interdrive.md ('Targets from the map').
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from langtraj.angles import wrap_angle
from langtraj.errors import InputError
from langtraj.interdrive.behaviour import BEHAVIOURS, Behaviour
from langtraj.interdrive.counterfactual import (
    COMFORT_DECELERATION,
    AgentOnLane,
    CounterfactualConfig,
    Feasibility,
    branch_direction,
    branch_turn,
    junction_chains,
)
from langtraj.interdrive.mapindex import MapIndex, arc_lengths
from langtraj.scenario.model import FUTURE_STEPS, STEP_SECONDS, Scenario
from langtraj.scenario.types import AgentType, StateField

PULL_OVER_DECELERATION = 1.5
"""Braking a pull-over is planned with (m/s^2): gentler, as it also moves sideways."""
SPEED_CHANGE = 3.0
"""Speed gained or lost by speeding up or slowing down (m/s; the labelers need at least 1 m/s)."""
HORIZON_S = FUTURE_STEPS * STEP_SECONDS
"""The simulated future the target must fit in (s)."""
ROUTE_SPACING = 1.0
"""Spacing of a target's path points (m)."""
LANE_CHANGE_S = 3.0
"""Time a lane change takes to settle in its new lane (s)."""
LANE_CHANGE_MIN_M = 15.0
"""Least length of the new lane before its next junction that a lane change needs (m)."""
KERB_CLEARANCE = 0.4
"""Gap left between a pulled-over vehicle's side and the road edge (m)."""


@dataclass(frozen=True)
class BehaviourTarget:
    """Where `behaviour` takes agent `track_id` (world frame, metres, seconds from the current step).

    `path` [N, 2] is the centreline to drive along (empty when the map gives none); `station_of_goal` is how far
    along it the agent must get (a turn: past the junction's exit) or must not pass (a stop, a pull-over, a
    yield: the stop or conflict point), with `stop` True when it must stand still there. `speed` is a target
    speed where the behaviour sets one. A pair behaviour names `other_id`, the `conflict` point [2] of the two
    paths (None when they do not cross), the `other_eta` (s) at which the other agent reaches it at its current
    speed, and `first` (whether the agent passes the conflict point first). `lateral_from` is the station from
    which a lane change or pull-over holds the offset path. `reason` says how the target was derived."""

    track_id: int
    behaviour: Behaviour
    path: np.ndarray
    reason: str
    station_of_goal: float | None = None
    stop: bool = False
    speed: float | None = None
    lateral_from: float = 0.0
    other_id: int | None = None
    conflict: np.ndarray | None = None
    other_eta: float | None = None
    first: bool | None = None
    current_speed: float = 0.0
    other_speed: float | None = None

    @property
    def goal_point(self) -> np.ndarray | None:
        """The point of `path` at `station_of_goal` [2] (None without one)."""
        if self.station_of_goal is None or len(self.path) < 2:
            return None
        return point_at_station(self.path, self.station_of_goal)

    def to_json(self) -> dict[str, Any]:
        """JSON-ready: the path every 2 m and the points rounded to centimetres (world frame)."""
        goal = self.goal_point
        return {
            "track_id": self.track_id,
            "behaviour": self.behaviour.value,
            "reason": self.reason,
            "path": np.round(self.path[:: max(1, round(2.0 / ROUTE_SPACING))], 2).tolist(),
            "goal": None if goal is None else [round(float(v), 2) for v in goal],
            "stop": self.stop,
            "speed": self.speed,
            "other_id": self.other_id,
            "conflict": None if self.conflict is None else [round(float(v), 2) for v in self.conflict],
            "first": self.first,
        }


class TargetUnavailable(InputError):
    """The map does not give a target for the behaviour (no lanes, no such branch, no neighbour lane)."""


# ---------------------------------------------------------------------------------------------- polylines


def stations(path: np.ndarray) -> np.ndarray:
    """Arc length [N] at each point of a polyline [N, 2] (`mapindex.arc_lengths`; empty for no points)."""
    return arc_lengths(path) if len(path) else np.zeros(0)


def point_at_station(path: np.ndarray, station: float) -> np.ndarray:
    """The point [2] of a polyline at arc length `station` (clamped to its ends)."""
    arc = stations(path)
    return np.array([np.interp(station, arc, path[:, 0]), np.interp(station, arc, path[:, 1])])


def project_station(path: np.ndarray, point: np.ndarray) -> tuple[float, float]:
    """Arc length of the point of `path` nearest to `point`, and the distance to it."""
    start, end = path[:-1], path[1:]
    direction = end - start
    length2 = np.maximum((direction**2).sum(-1), 1e-12)
    t = np.clip(((point - start) * direction).sum(-1) / length2, 0.0, 1.0)
    closest = start + t[:, None] * direction
    gap = np.linalg.norm(closest - point, axis=1)
    k = int(np.argmin(gap))
    return float(stations(path)[k] + t[k] * math.sqrt(length2[k])), float(gap[k])


def _resample(points: np.ndarray, spacing: float = ROUTE_SPACING) -> np.ndarray:
    arc = stations(points)
    if len(points) < 2 or arc[-1] <= 0:
        return points[:1].copy()
    at = np.linspace(0.0, arc[-1], max(int(arc[-1] / spacing) + 1, 2))
    return np.stack([np.interp(at, arc, points[:, 0]), np.interp(at, arc, points[:, 1])], -1)


def _lane_piece(index: MapIndex, lane: int, start: float = 0.0) -> np.ndarray:
    """Lane `lane`'s centreline from `start` (m) to its end."""
    points = np.asarray(index.lane_features[lane].points[:, :2], np.float64)
    arc = stations(points)
    keep = arc > start
    head = point_at_station(points, start)[None]
    return np.concatenate([head, points[keep]]) if keep.any() else head


def _join(pieces: list[np.ndarray]) -> np.ndarray:
    out = [p for p in pieces if len(p)]
    return _resample(np.concatenate(out)) if out else np.zeros((0, 2))


def _straightest_exit(index: MapIndex, lane: int) -> int | None:
    """The exit of `lane` whose heading changes least (None at a dead end)."""
    exits = index.exits[lane]
    if not exits:
        return None
    end = index.heading_at(lane, float(index.lane_lengths[lane]))
    return min(exits, key=lambda e: abs(float(wrap_angle(index.heading_at(e, 0.0) - end))))


def _route(index: MapIndex, lanes: list[int], start: float, length: float) -> np.ndarray:
    """The centreline along `lanes` from `start` on the first, continued by the straightest exits until
    `length` m."""
    pieces = [_lane_piece(index, lanes[0], start)]
    done = float(index.lane_lengths[lanes[0]]) - start
    for lane in lanes[1:]:
        pieces.append(_lane_piece(index, lane))
        done += float(index.lane_lengths[lane])
    last, seen = lanes[-1], set(lanes)
    while done < length:
        nxt = _straightest_exit(index, last) if index.has_connectivity else None
        if nxt is None or nxt in seen:
            break
        pieces.append(_lane_piece(index, nxt))
        done += float(index.lane_lengths[nxt])
        last = nxt
        seen.add(nxt)
    path = _join(pieces)
    return path[: int(length / ROUTE_SPACING) + 2]


# ---------------------------------------------------------------------------------------------- derivation


@dataclass(frozen=True)
class _Agent:
    row: int
    track_id: int
    here: AgentOnLane
    xy: np.ndarray
    heading: float
    length: float
    width: float

    @property
    def reach(self) -> float:
        """How far the route ahead is drawn (m): beyond what the horizon can cover."""
        return max(60.0, (self.here.speed + SPEED_CHANGE) * HORIZON_S + 20.0)


def _agent(scenario: Scenario, track_id: int, index: MapIndex, config: CounterfactualConfig) -> _Agent:
    row = scenario.agents.index_of(track_id)
    c = scenario.current_index
    if not scenario.agents.valid[row, c]:
        raise TargetUnavailable(f"@{track_id} is not valid at the current step", where="target")
    state = scenario.agents.states[row, c]
    here = AgentOnLane.of(scenario, row, index, config.heuristics)
    return _Agent(
        row,
        track_id,
        here,
        state[[StateField.X, StateField.Y]].astype(np.float64),
        float(state[StateField.HEADING]),
        float(state[StateField.LENGTH]),
        float(state[StateField.WIDTH]),
    )


def _need_lane(agent: _Agent, index: MapIndex, what: str) -> None:
    if not index.has_lanes:
        raise TargetUnavailable(f"the map has no lanes to find {what} of @{agent.track_id}", where="target")
    if agent.here.lane < 0:
        raise TargetUnavailable(f"@{agent.track_id} is on no lane, so {what} is unknown", where="target")


def _ahead(agent: _Agent, index: MapIndex) -> np.ndarray:
    _need_lane(agent, index, "the lane ahead")
    return _route(index, [agent.here.lane], agent.here.station, agent.reach)


def derive_target(
    scenario: Scenario,
    track_id: int,
    behaviour: Behaviour,
    index: MapIndex,
    *,
    other_id: int | None = None,
    config: CounterfactualConfig | None = None,
) -> BehaviourTarget:
    """The target of `behaviour` for `track_id` at the scenario's current step (see the module docstring).
    Raises `TargetUnavailable` (an InputError) naming the agent and the reason where the map gives none."""
    config = config or CounterfactualConfig()
    spec = BEHAVIOURS[behaviour]
    if spec.is_pair and other_id is None:
        raise InputError(f"behaviour {behaviour.value!r} needs another agent", where="target")
    agent = _agent(scenario, track_id, index, config)
    if spec.is_turn:
        return _turn_target(agent, behaviour, index, config)
    if spec.is_lane_change:
        return _lane_change_target(agent, behaviour, index, str(spec.side))
    if behaviour is Behaviour.STOP:
        return _stop_target(scenario, agent, index)
    if behaviour is Behaviour.PULL_OVER:
        return _pull_over_target(agent, index)
    if behaviour in (Behaviour.SPEED_UP, Behaviour.SLOW_DOWN):
        v = agent.here.speed
        speed = v + SPEED_CHANGE if behaviour is Behaviour.SPEED_UP else max(v - SPEED_CHANGE, 0.35 * v)
        return BehaviourTarget(
            track_id, behaviour, _ahead(agent, index), f"its lane ahead at {speed:.1f} m/s", speed=speed,
            current_speed=v,
        )  # fmt: skip
    other = _agent(scenario, int(other_id), index, config)  # type: ignore[arg-type]
    if behaviour is Behaviour.FOLLOW:
        path = _ahead(other, index) if other.here.lane >= 0 else np.zeros((0, 2))
        return BehaviourTarget(
            track_id, behaviour, path, f"behind @{other_id} along its lane", other_id=other.track_id,
            current_speed=agent.here.speed, other_speed=other.here.speed,
        )  # fmt: skip
    return _order_target(agent, other, behaviour, index, config)


def _branches(
    agent: _Agent, index: MapIndex, config: CounterfactualConfig, direction: Behaviour | None = None
) -> list[tuple[float, list[int]]]:
    """The branches of the next junction on the agent's lanes (in `direction` only, when given): for each, the
    distance to its exit and its lanes from the agent's (feasibility's search, `counterfactual`)."""
    lane, station = agent.here.lane, agent.here.station
    wanted = (lambda turn: True) if direction is None else (lambda turn: branch_direction(turn, config) is direction)
    found: list[tuple[float, list[int]]] = []
    if index.is_junction[lane]:  # inside the junction: what is left of its own branch decides
        for chain in junction_chains(index, lane):
            if wanted(branch_turn(index, chain, station)):
                found.append((float(sum(index.lane_lengths[x] for x in chain)) - station, chain))
    frontier: list[tuple[int, float, list[int]]] = [] if index.is_junction[lane] else [(lane, -station, [lane])]
    seen = {lane}
    while frontier and not found:
        current, start, before = frontier.pop(0)
        end = start + float(index.lane_lengths[current])
        for nxt in index.exits[current]:
            if end > agent.reach or nxt in seen:
                continue
            seen.add(nxt)
            if index.is_junction[nxt]:
                for chain in junction_chains(index, nxt):
                    if wanted(branch_turn(index, chain)):
                        found.append((max(end, 0.0) + float(sum(index.lane_lengths[x] for x in chain)), before + chain))
            else:
                frontier.append((nxt, end, [*before, nxt]))
    return found


def _paths_ahead(agent: _Agent, index: MapIndex, config: CounterfactualConfig) -> list[np.ndarray]:
    """Every way the agent may go: its lane ahead by the straightest exits first, then each branch of the next
    junction; off lanes, the line along its heading."""
    first = _ahead_or_straight(agent, index)
    if not (index.has_lanes and index.has_connectivity and agent.here.lane >= 0):
        return [first]
    return [first] + [
        _route(index, lanes, agent.here.station, max(agent.reach, exit_at + 25.0))
        for exit_at, lanes in _branches(agent, index, config)
    ]


def _turn_target(agent: _Agent, behaviour: Behaviour, index: MapIndex, config: CounterfactualConfig) -> BehaviourTarget:
    """The branch of the next junction in the asked direction: the lanes to it, the junction lanes, and past the
    exit; the goal station lies 5 m past the junction."""
    _need_lane(agent, index, "the junction ahead")
    if not index.has_connectivity:
        raise TargetUnavailable("the map has no lane connectivity to follow to a junction", where="target")
    found = _branches(agent, index, config, behaviour)
    if not found:
        raise TargetUnavailable(
            f"@{agent.track_id} cannot {BEHAVIOURS[behaviour].manoeuvre}: no such branch at the next junction within "
            f"{agent.reach:.0f} m",
            where="target",
        )
    exit_at, lanes = min(found, key=lambda item: item[0])
    goal = exit_at + 5.0
    path = _route(index, lanes, agent.here.station, max(agent.reach, goal + 25.0))
    return BehaviourTarget(
        agent.track_id,
        behaviour,
        path,
        f"the {BEHAVIOURS[behaviour].manoeuvre} branch of the next junction, its exit {exit_at:.0f} m ahead",
        station_of_goal=goal,
        current_speed=agent.here.speed,
    )


def _lane_change_target(agent: _Agent, behaviour: Behaviour, index: MapIndex, side: str) -> BehaviourTarget:
    """The neighbour lane on `side`: the first lane parallel to the agent's, 2.5 to 4.5 m to that side, found
    along its lane ahead from where a lane change can begin (1 s or 4 m ahead), with room before its next junction
    for the change to settle (`LANE_CHANGE_S` at the agent's speed, at least `LANE_CHANGE_MIN_M`: the labelers
    count no change into a junction lane)."""
    _need_lane(agent, index, f"the lane on its {side}")
    ahead = _ahead(agent, index)
    arc = stations(ahead)
    sign = 1.0 if side == "left" else -1.0
    begin = max(4.0, 1.0 * agent.here.speed)
    for s in np.arange(begin, min(arc[-1], begin + 40.0), 2.0):
        point = point_at_station(ahead, s)
        k = min(int(np.searchsorted(arc, s)), len(ahead) - 1)
        d = ahead[min(k + 1, len(ahead) - 1)] - ahead[max(k - 1, 0)]
        heading = math.atan2(d[1], d[0])
        normal = np.array([-math.sin(heading), math.cos(heading)]) * sign
        match = index.match_lanes(
            (point + 3.5 * normal)[None], np.array([heading]), radius=1.5, max_heading_diff=math.radians(30.0)
        )
        lane = int(match.lane[0])
        if lane < 0 or index.is_junction[lane] or lane == agent.here.lane:
            continue
        _, lateral = index.project_to_lane(lane, point[None])
        if not (2.5 <= abs(float(lateral[0])) <= 4.5) or np.sign(-lateral[0]) != sign:
            continue
        room = index.distance_to_junction(lane, float(match.station[0])) if index.has_connectivity else math.inf
        if room < max(LANE_CHANGE_MIN_M, LANE_CHANGE_S * agent.here.speed):
            continue  # the lane beside it runs into a junction before a change could settle in it
        path = _route(index, [lane], float(match.station[0]), agent.reach)
        lead_in = _resample(np.stack([agent.xy, path[0]]))
        return BehaviourTarget(
            agent.track_id,
            behaviour,
            np.concatenate([lead_in[:-1], path]),
            f"the lane on its {side}, from {s:.0f} m ahead",
            lateral_from=float(stations(lead_in)[-1]),
            current_speed=agent.here.speed,
        )
    raise TargetUnavailable(f"@{agent.track_id} has no lane on its {side} along its road", where="target")


def _stop_target(scenario: Scenario, agent: _Agent, index: MapIndex) -> BehaviourTarget:
    """A stop on the lane ahead where comfortable braking brings the agent to rest; at a stop line (the start of
    the next junction or a signal's stop point) or before a crosswalk when one lies a little beyond that, but no
    farther than the agent gets braking evenly over 7 s."""
    path = _ahead(agent, index)
    v = agent.here.speed
    comfort = v * v / (2 * COMFORT_DECELERATION) + 0.5 * agent.length
    latest = max(comfort, 0.5 * v * 7.0)
    arc = stations(path)
    reason, station = f"where braking at {COMFORT_DECELERATION:g} m/s^2 brings it to rest", comfort
    marks: list[tuple[float, str]] = []
    if index.has_connectivity and not index.is_junction[agent.here.lane]:
        marks.append((index.distance_to_junction(agent.here.lane, agent.here.station) - 1.0, "at the stop line"))
    lights = scenario.traffic_lights
    if lights is not None and len(lights.stop_points):
        for point in np.asarray(lights.stop_points)[:, :2]:
            s, gap = project_station(path, point)
            if gap < 2.5:
                marks.append((s - 1.0, "at the signal's stop line"))
    crossing = index.in_crosswalk(path) if index.has_crosswalks else np.zeros(len(path), bool)
    if crossing.any():
        marks.append((float(arc[int(np.argmax(crossing))]) - 2.0, "before the crosswalk"))
    for s, why in sorted(marks):
        if comfort <= s + 0.5 * agent.length <= latest + 0.5 * agent.length:
            station, reason = s, why
            break
    return BehaviourTarget(
        agent.track_id,
        Behaviour.STOP,
        path,
        f"a stop {station:.0f} m ahead, {reason}",
        station_of_goal=float(station),
        stop=True,
        speed=0.0,
        current_speed=v,
    )


def _pull_over_target(agent: _Agent, index: MapIndex) -> BehaviourTarget:
    """The lane ahead shifted to the right, to the kerb (the road edge less half the width and a clearance, at
    least 0.8 m off the centre) or half a lane where the map has no road edges, and a stop where gentle braking
    brings the agent to rest."""
    lane_path = _ahead(agent, index)
    v = agent.here.speed
    stop = max(v * v / (2 * PULL_OVER_DECELERATION), 2.0 * v, 8.0)
    stop = min(stop, max(0.5 * v * 5.5, 8.0))
    point = point_at_station(lane_path, stop)
    offset, reason = 1.2, "half a lane to its right (the map has no road edges)"
    if index.has_road_edges:
        k = min(int(stop / ROUTE_SPACING), len(lane_path) - 2)
        d = lane_path[k + 1] - lane_path[k]
        right = np.array([d[1], -d[0]]) / max(float(np.linalg.norm(d)), 1e-9)
        probes = point[None] + np.arange(0.5, 8.01, 0.25)[:, None] * right[None]
        near = index.distance_to_road_edge(probes, 1.0)
        hit = np.flatnonzero(np.isfinite(near))
        if hit.size:
            kerb = 0.5 + 0.25 * int(hit[0])
            offset = float(np.clip(kerb - 0.5 * agent.width - KERB_CLEARANCE, 0.8, 3.0))
            reason = f"the kerb {kerb:.1f} m to its right"
    arc = stations(lane_path)
    begin = min(max(0.3 * stop, 3.0), stop)
    shift = offset * np.clip((arc - begin) / max(stop - begin, 1.0), 0.0, 1.0)
    tangent = np.gradient(lane_path, axis=0)
    tangent /= np.maximum(np.linalg.norm(tangent, axis=1, keepdims=True), 1e-9)
    right = np.stack([tangent[:, 1], -tangent[:, 0]], -1)
    return BehaviourTarget(
        agent.track_id,
        Behaviour.PULL_OVER,
        lane_path + shift[:, None] * right,
        f"a stop {stop:.0f} m ahead, {reason}",
        station_of_goal=float(stop),
        stop=True,
        speed=0.0,
        lateral_from=float(begin),
        current_speed=v,
    )


def _crossing(mine: np.ndarray, theirs: np.ndarray) -> tuple[int, float] | None:
    """The index of the first point of path `mine` within 2 m of path `theirs` at more than 20 degrees to it, and
    the other's distance along `theirs` to there; None when they do not cross."""
    if len(mine) < 2 or len(theirs) < 2:
        return None
    gaps = np.linalg.norm(mine[:, None] - theirs[None], axis=-1)
    hm = np.arctan2(*np.gradient(mine, axis=0).T[::-1])
    ht = np.arctan2(*np.gradient(theirs, axis=0).T[::-1])
    crossing = (gaps < 2.0) & (np.abs(wrap_angle(hm[:, None] - ht[None, :])) > math.radians(20.0))
    rows = np.flatnonzero(crossing.any(axis=1))
    if not rows.size:
        return None
    i = int(rows[0])
    j = int(np.argmin(np.where(crossing[i], gaps[i], np.inf)))
    return i, float(stations(theirs)[j])


def _ahead_or_straight(agent: _Agent, index: MapIndex) -> np.ndarray:
    """The agent's lane ahead, or, off lanes (a pedestrian, a cyclist), the line along its heading."""
    if index.has_lanes and agent.here.lane >= 0:
        return _route(index, [agent.here.lane], agent.here.station, agent.reach)
    forward = np.array([math.cos(agent.heading), math.sin(agent.heading)])
    reach = max(20.0, agent.here.speed * HORIZON_S + 10.0)
    return agent.xy[None] + np.arange(0.0, reach, ROUTE_SPACING)[:, None] * forward[None]


def _order_target(
    agent: _Agent, other: _Agent, behaviour: Behaviour, index: MapIndex, config: CounterfactualConfig
) -> BehaviourTarget:
    """Going first or yielding: the first point of the agent's path ahead that a path of the other agent crosses at
    more than 20 degrees, and when the other gets there at its current speed. Paths are the lanes ahead by the
    straightest exits and then each branch of the next junction (`_paths_ahead`): the agent's first path that any
    of the other's crosses is taken, with its earliest crossing."""
    first = behaviour is Behaviour.GO_FIRST
    mine = _ahead_or_straight(agent, index)
    conflict, eta, reason = None, None, f"no crossing of its lane with @{other.track_id}'s ahead"
    theirs = _paths_ahead(other, index, config)
    for path in _paths_ahead(agent, index, config):
        crossings = [c for c in (_crossing(path, t) for t in theirs) if c is not None]
        if crossings:
            i, distance = min(crossings)
            mine, conflict = path, path[i]
            eta = distance / max(other.here.speed, 1.0)
            order = "before" if first else "after"
            reason = f"it passes the conflict point {stations(path)[i]:.0f} m ahead {order} @{other.track_id}"
            break
    station = None if conflict is None else project_station(mine, conflict)[0]
    return BehaviourTarget(
        agent.track_id,
        behaviour,
        mine,
        reason,
        station_of_goal=station,
        other_id=other.track_id,
        conflict=conflict,
        other_eta=eta,
        first=first,
        current_speed=agent.here.speed,
        other_speed=other.here.speed,
    )


GO_FIRST_ACCELERATION = 2.5
"""The most an agent asked to go first is assumed to speed up by (m/s^2), up to `GO_FIRST_TOP_SPEED`."""
GO_FIRST_TOP_SPEED = 15.0
GO_FIRST_MARGIN_S = 0.5
"""Going first must get the agent to the crossing this much earlier than the other agent at its speed (s)."""


def order_feasibility(
    scenario: Scenario,
    track_id: int,
    other_id: int,
    behaviour: Behaviour,
    index: MapIndex,
    config: CounterfactualConfig | None = None,
) -> Feasibility:
    """Whether `track_id` can go first at its crossing with `other_id` (yielding is always feasible: it can
    wait). Infeasible when a pedestrian or cyclist other is already within 3 m of the crossing point (it is
    crossing), or when the other agent, at its current speed, gets there before the agent can even speeding up at
    2.5 m/s^2; undecided where the map gives no crossing point."""
    if behaviour is not Behaviour.GO_FIRST:
        return Feasibility(track_id, behaviour, "feasible")
    try:
        target = derive_target(scenario, track_id, behaviour, index, other_id=other_id, config=config)
    except TargetUnavailable as exc:
        return Feasibility(track_id, behaviour, "undecided", exc.detail)
    if target.conflict is None or target.station_of_goal is None or target.other_eta is None:
        return Feasibility(track_id, behaviour, "undecided", target.reason)
    other = scenario.agents.index_of(other_id)
    here = scenario.agents.states[other, scenario.current_index, [StateField.X, StateField.Y]].astype(np.float64)
    if scenario.agents.types[other] != AgentType.VEHICLE and np.linalg.norm(here - target.conflict) < 3.0:
        return Feasibility(track_id, behaviour, "infeasible", f"@{other_id} is already crossing its path")
    need = _time_to_cover(target.station_of_goal, target.current_speed)
    if need + GO_FIRST_MARGIN_S >= target.other_eta:
        return Feasibility(
            track_id,
            behaviour,
            "infeasible",
            f"@{other_id} gets to the crossing in {target.other_eta:.1f} s; @{track_id} needs {need:.1f} s",
        )
    return Feasibility(track_id, behaviour, "feasible")


def _time_to_cover(distance: float, speed: float) -> float:
    """Seconds to cover `distance` m from `speed`, speeding up at `GO_FIRST_ACCELERATION` to the top speed."""
    a, top = GO_FIRST_ACCELERATION, max(GO_FIRST_TOP_SPEED, speed)
    ramp = (top - speed) / a
    ramp_distance = speed * ramp + 0.5 * a * ramp**2
    if distance <= ramp_distance:
        return (-speed + math.sqrt(speed**2 + 2 * a * distance)) / a
    return ramp + (distance - ramp_distance) / top
