"""Targets from the map: where a behaviour asked of an agent takes it, derived from the scene at the current step,
and the one answer to whether the agent can do it (a behaviour is feasible exactly when it has a target).

A prompt names a behaviour kind (`interdrive.behaviour`); guidance and candidate selection need something concrete
to steer toward, and counterfactual prompts need to know what the map allows. `assess` reads the agent's lane and
the lane graph (`lanes_ahead`) and returns either a `BehaviourTarget` in world coordinates or why there is none,
"infeasible" (the map rules it out) or "undecided" (the map lacks what it takes to tell):

- a turn or going straight: the lanes of the branch of the next junction in that direction, from the agent to past
  its exit;
- a lane change: the neighbour lane on that side (`MapIndex.neighbour_lane`) along its road ahead, with room before
  its next junction for the change to settle;
- a stop: the agent's lane ahead (off lanes, the line along its heading) and a stop station that comfortable braking
  reaches (a stop line or crosswalk when one lies a little beyond);
- pulling over: the agent moves in the lane next to the kerb with room before the next junction (where the
  junction is too near, the kerb lane past it); the lane ahead shifted toward the kerb, and a stop station;
- speeding up or slowing down (the agent moves): the lane ahead and a target speed;
- going first or yielding: both agents' ways ahead, the conflict point where they cross, and the order; going first
  needs a crossing the agent can reach first;
- following: the other agent's lane ahead;
- cutting in front of another agent: the other's lane, beside the agent's, from where a change can begin, and the
  average speed that puts the agent the asked gap ahead of the other when the change settles;
- overtaking another agent and cutting in front of it (the agent behind or beside it, in a lane beside its own):
  its own lane until its rear is past the other's front, then the other's lane, settled the asked gap ahead of it;
- braking hard in front of another agent (which follows it in its lane): the agent's lane ahead and the stop that
  braking at the asked deceleration from 1 s on brings it to;
- tailgating another agent (ahead of it in its lane): the agent's lane ahead, the station that closes the gap to
  0.4 s of headway within a few seconds, and the other's speed after;
- running a red light across another agent's way: its way through a signal showing stop at the current step, and
  the crossing with the other's way past it, to be passed first;
- pulling out in front of another agent from a side road, a driveway or the kerb (the agent nearly standing): the
  first of its ways (off lanes, a straight line) that meets the other's way ahead of it, set off so that it is there
  `PULL_OUT_GAP_S` before the other;
- a turn or a lane change and then a stop (`stop_after`): the manoeuvre's path, and a stop past where it is done.

Only the current step and the past are read (never the logged future), so a simulation may use the target.
See docs/interdrive.md ('Targets and feasibility').
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, replace
from typing import Any, Literal

import numpy as np

from langtraj.angles import wrap_angle
from langtraj.errors import InputError
from langtraj.interdrive.behaviour import BEHAVIOURS, Behaviour, Side
from langtraj.interdrive.detector.config import DetectorConfig
from langtraj.interdrive.targets.config import CounterfactualConfig
from langtraj.interdrive.targets.lanes_ahead import (
    AgentOnLane,
    JunctionAhead,
    StationAhead,
    branch_direction,
    junction_ahead,
    stations_ahead,
)
from langtraj.interdrive.taxonomy import LABELS_BY_KEY
from langtraj.polylines import arc_lengths, point_at, project_on_polyline, resample
from langtraj.roads import MapIndex
from langtraj.roads.routes import ROUTE_SPACING, route, straight_line
from langtraj.scenario.model import FUTURE_STEPS, STEP_SECONDS, Scenario
from langtraj.scenario.types import RED_STATES, AgentType, StateField, TrafficLightState

Status = Literal["feasible", "infeasible", "undecided"]

_JUDGE = DetectorConfig()
"""The judge's thresholds (`interdrive.detector`), which a target that must be judged to happen starts from."""

COMFORT_DECELERATION = 2.0
"""Comfortable braking (m/s^2): a stop lies where it brings the agent to rest, and a pull-over needs room to stop
this way before the next junction."""
KERB_PAST_JUNCTION_M = 12.0
"""How far past a junction's exit a pull-over stops when the kerb before the junction is too near (m): room to move
across after leaving the junction lane."""
PULL_OVER_DECELERATION = 1.5
"""Braking a pull-over is planned with (m/s^2): gentler, as it also moves sideways."""
SPEED_CHANGE = 3.0
"""Speed gained or lost by speeding up or slowing down (m/s; the labelers need at least 1 m/s)."""
HORIZON_S = FUTURE_STEPS * STEP_SECONDS
"""The simulated future the target must fit in (s)."""
LANE_CHANGE_S = 3.0
"""Time a lane change takes to settle in its new lane (s)."""
LANE_CHANGE_MIN_M = 15.0
"""Least length of the new lane before its next junction that a lane change needs (m)."""
KERB_CLEARANCE = 0.4
"""Gap a pulled-over vehicle's side is asked to leave to the road edge (m), where the road is wide enough."""
KERB_MIN_CLEARANCE = 0.1
"""The least gap to the road edge a pull-over is asked for (m), where the lane is too narrow for both
`KERB_CLEARANCE` and the target's least shift of 0.8 m."""
KERB_SEARCH_M = 8.0
"""How far to the right of its lane a pull-over looks for the road edge (m)."""
CROSSING_RADIUS = 2.0
"""Two paths ahead cross where they come this close (m) at more than `CROSSING_ANGLE` (a target's conflict point,
on map paths, before anything is driven; the judge's yield rule is the detector's, on driven tracks)."""
CROSSING_ANGLE = math.radians(20.0)
GO_FIRST_ACCELERATION = 2.5
"""The most an agent asked to go first is assumed to speed up by (m/s^2), up to `GO_FIRST_TOP_SPEED`."""
GO_FIRST_TOP_SPEED = 15.0
CUT_IN_GAP_M = 10.0
"""The gap (bumper to bumper, m) a cut-in leaves in front of the other agent unless the prompt gives one."""
CUT_IN_S = 1.0 + LANE_CHANGE_S
"""When a cut-in has settled in the other's lane (s): begun within 1 s, settled `LANE_CHANGE_S` later."""
OVERTAKE_GAIN = 4.0
"""How much faster than the other agent an overtake passes it (m/s), unless the agent is faster already."""
OVERTAKE_LATEST_S = HORIZON_S - 1.0
"""By when an overtake must have settled in the other's lane (s): a second before the horizon, for the judge."""
OVERTAKE_MIN_SPEED = 5.0
"""The least speed of the agent overtaken (m/s): slower traffic is queued, not overtaken."""
OVERTAKE_CLEAR_M = 2.0
"""How far an overtaking agent's rear is past the other's front when its change into the other's lane begins (m),
unless the asked gap is smaller."""
GO_FIRST_MARGIN_S = 0.5
"""Going first must get the agent to the crossing this much earlier than the other agent at its speed (s)."""
NOT_GO_STATES = tuple(s for s in TrafficLightState if s.is_stop or s.is_caution)
"""Signal states that stop a lane or are about to: the other agent must face none of these before the crossing (it
has the right of way a red-light runner cuts)."""
RED_LIGHT_SPEED = 8.0
"""The least speed a red-light runner crosses at (m/s): a car that jumps the light does not creep."""
RED_LIGHT_REACH_S = 4.0
"""How far ahead, in time at that speed, the red light may be (s): later, it may well have turned green."""
RED_STOP_LATERAL = 1.5
"""How close to a way a signal's stop point must lie to be that way's (m; lanes are about 3.5 m apart)."""
BRAKE_HARD_DECELERATION = 4.0
"""How hard a braking lead brakes unless the prompt says (m/s^2): Euro NCAP's braking-lead tests use 2 to 6."""
BRAKE_HARD_LIMITS = (3.0, 10.0)
"""The decelerations a braking lead may be asked for (m/s^2): at least the judge's hard braking
(`DetectorConfig.hard_braking`), at most what tyres give on dry asphalt (about 1 g)."""
BRAKE_HARD_AFTER_S = 1.0
"""When a braking lead starts braking (s): the follower has a second of the scene as it was."""
BRAKE_HARD_MIN_SPEED = 4.0
"""The least speed a braking lead must have (m/s): slower, hard braking lasts too short to judge."""
FOLLOWER_RANGE_M = 40.0
"""How far (bumper to bumper, m) behind a braking lead, or ahead of a tailgater, the other agent may be."""
TAILGATE_HEADWAY_S = 0.4
"""The time gap a tailgater closes to (s): under the judge's 0.6 s (`DetectorConfig.tailgating_headway_s`)."""
TAILGATE_MIN_SPEED = 6.0
"""The least speed of the agent tailgated (m/s): the judge's tailgating needs 5 m/s."""
TAILGATE_CLOSING = 3.0
"""How much faster than the other a tailgater closes the gap (m/s on average), within `TAILGATE_WITHIN_S`."""
TAILGATE_WITHIN_S = 6.0
"""The latest a tailgater must have closed to its short headway (s): later, the judge may not see it tailgate."""
PULL_OUT_MAX_SPEED = _JUDGE.pull_out_speed
"""The most an agent asked to pull out may be moving (m/s; the judge's): a pull-out starts from standing or a
crawl."""
PULL_OUT_OTHER_MIN_SPEED = _JUDGE.pull_out_other_speed
"""The least speed of the agent pulled out in front of (m/s; the judge's)."""
PULL_OUT_REACH_M = 30.0
"""How far along its way an agent pulling out may meet the other's way (m): farther, it is driving, not pulling out."""
PULL_OUT_MEET_M = 1.0
"""The agent's way meets the other's where it comes this close to it (m)."""
PULL_OUT_GAP_S = 2.0
"""How long before the other agent gets there the agent is where it pulls out onto the other's way (s), setting off
later where the other is farther: the two-second rule, broken for the other as the agent noses in."""
PULL_OUT_MIN_GAP_S = 1.0
"""The least such time (s): less, and the other cannot brake for it (a crash, not a pull-out)."""
PULL_OUT_LATEST_S = HORIZON_S - 2.0
"""The latest the other may get to where the agent pulls out (s): the judge sees the two after it."""
PULL_OUT_TOP_SPEED = 10.0
"""The speed an agent that has pulled out drives on at (m/s), or the other's, if slower."""
PULL_OUT_OFF_WAY_M = _JUDGE.red_conflict_radius
"""How far from the other's way an agent pulling out must be (m; the judge's): nearer, it is on that way already (in
the lane, or standing in the junction across it)."""
STOP_AFTER_M = 2.0
"""How far past where a manoeuvre is done a stop asked after it lies (m): a turn is done 5 m past the junction's exit,
so its stop lies 7 m past the exit, the car wholly out of the junction."""
LANE_CHANGE_DONE_S = 4.0
"""When a lane change is done (s): its steering holds the agent in the new lane from then (`guidance.steering`)."""
STOP_AFTER_BY_S = HORIZON_S - 1.0
"""The latest a stop asked after a manoeuvre may begin to stand (s): the labelers see a stop of 1 s or more."""
STOP_AFTER_MIN_SPEED = 3.0
"""The speed (m/s) a slower agent is taken to set off at to reach a stop past its manoeuvre."""


@dataclass(frozen=True)
class BehaviourTarget:
    """Where `behaviour` takes agent `track_id` (world frame, metres, seconds from the current step).

    `path` [N, 2] is the centreline to drive along (empty when the map gives none); `station_of_goal` is how far
    along it the agent must get (a turn: past the junction's exit) or must not pass (a stop, a pull-over, a
    yield: the stop or conflict point). `speed` is a target speed where the behaviour sets one (0: it stops). A pair
    behaviour names `other_id`, the `conflict` point [2] of the two paths (None when they do not cross) and the
    `other_eta` (s) at which the other agent reaches it at its current speed. `reason` says how the target was
    derived."""

    track_id: int
    behaviour: Behaviour
    path: np.ndarray
    reason: str
    station_of_goal: float | None = None
    speed: float | None = None
    other_id: int | None = None
    conflict: np.ndarray | None = None
    other_eta: float | None = None
    current_speed: float = 0.0
    other_speed: float | None = None
    side: Side | None = None
    """The side it moves across to (a lane change, a cut-in), where there is one."""
    settled_s: float | None = None
    """When the agent must be at `station_of_goal` (s), where the target times it (a cut-in, a tailgate, a braking
    lead at rest)."""
    deceleration: float | None = None
    """How hard it brakes (m/s^2), where the target says (a braking lead)."""
    lead_m: float | None = None
    """How far the agent's centre is ahead of the other's along the path once settled (m), where the target says (a
    cut-in, an overtake and cut-in: the gap and the half lengths), so that steering can keep it relative to where
    the other actually drives."""
    starts_s: float | None = None
    """When the agent sets off (s), where the target has it wait first (a pull-out waiting for its moment)."""
    joins_m: float | None = None
    """How far along the path it joins its new lane (m), where the target changes lanes (a lane change: where its
    lead-in meets the lane), so that what is asked after the change lies past it (`stop_after`)."""

    @property
    def stop(self) -> bool:
        """Whether the agent must come to rest at `station_of_goal`."""
        return self.speed == 0.0

    @property
    def first(self) -> bool | None:
        """Whether the agent passes the conflict point first (None for a single-agent behaviour)."""
        return None if self.other_id is None else self.behaviour in _FIRST

    @property
    def goal_point(self) -> np.ndarray | None:
        """The point of `path` at `station_of_goal` [2] (None without one)."""
        if self.station_of_goal is None or len(self.path) < 2:
            return None
        return point_at(self.path, self.station_of_goal)

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


_FIRST = (Behaviour.GO_FIRST, Behaviour.RUN_RED_LIGHT, Behaviour.PULL_OUT)
"""The pair kinds whose agent gets to the conflict point first."""


class TargetUnavailable(InputError):
    """The map gives no target for the behaviour: it is "infeasible" there (the map rules it out) or "undecided"
    (the map lacks what it takes to tell); `reason` says why, without naming the agent."""

    def __init__(self, track_id: int, behaviour: Behaviour, status: Status, reason: str):
        self.track_id, self.behaviour, self.status, self.reason = track_id, behaviour, status, reason
        super().__init__(f"@{track_id} cannot {BEHAVIOURS[behaviour].manoeuvre}: {reason}", where="target")


# ---------------------------------------------------------------------------------------------- the agent


@dataclass(frozen=True)
class _Agent:
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
    (`feasibility.behaviour_feasibility`) reads the map once. `target` derives one target."""

    def __init__(self, scenario: Scenario, index: MapIndex, config: CounterfactualConfig | None = None):
        self.scenario, self.index, self.config = scenario, index, config or CounterfactualConfig()
        self._agents: dict[int, _Agent | None] = {}
        self._junctions: dict[int, JunctionAhead] = {}
        self._stations: dict[int, list[StationAhead]] = {}

    def agent(self, track_id: int, behaviour: Behaviour) -> _Agent:
        """Agent `track_id` at the current step; `TargetUnavailable` (undecided) when it is not valid there."""
        if track_id not in self._agents:
            self._agents[track_id] = self._read(track_id)
        found = self._agents[track_id]
        if found is None:
            raise TargetUnavailable(track_id, behaviour, "undecided", "it is not valid at the current step")
        return found

    def _read(self, track_id: int) -> _Agent | None:
        row = self.scenario.agents.index_of(track_id)
        c = self.scenario.current_index
        if not self.scenario.agents.valid[row, c]:
            return None
        state = self.scenario.agents.states[row, c]
        cfg = self.config.heuristics
        here = AgentOnLane.of(
            self.scenario, row, self.index, radius=cfg.lane_match_radius, max_heading=cfg.lane_match_max_heading
        )
        return _Agent(
            track_id,
            AgentType(int(self.scenario.agents.types[row])),
            here,
            state[[StateField.X, StateField.Y]].astype(np.float64),
            float(state[StateField.HEADING]),
            float(state[StateField.LENGTH]),
            float(state[StateField.WIDTH]),
            self.config.reach(here.speed),
        )

    def junction(self, agent: _Agent) -> JunctionAhead:
        """The branches of the agent's next junction within its search (`lanes_ahead.junction_ahead`)."""
        if agent.track_id not in self._junctions:
            self._junctions[agent.track_id] = junction_ahead(self.index, agent.here, agent.search, self.config)
        return self._junctions[agent.track_id]

    def stations(self, agent: _Agent) -> list[StationAhead]:
        """The stations of the agent's road ahead within its search (`lanes_ahead.stations_ahead`)."""
        if agent.track_id not in self._stations:
            self._stations[agent.track_id] = stations_ahead(self.index, agent.here, agent.search, self.config)
        return self._stations[agent.track_id]

    def target(
        self,
        track_id: int,
        behaviour: Behaviour,
        other_id: int | None = None,
        gap: float | None = None,
        deceleration: float | None = None,
    ) -> BehaviourTarget:
        """The target of `behaviour` for `track_id` (toward `other_id` for a pair behaviour; a cut-in `gap` m ahead
        of it; a braking lead at `deceleration` m/s^2), or `TargetUnavailable` (see the module docstring)."""
        return _target(self, track_id, behaviour, other_id, gap, deceleration)

    def moving(self, agent: _Agent) -> bool:
        """Faster than the labelers' standing speed by their least speed change."""
        cfg = self.config.heuristics
        return agent.here.speed > cfg.static_speed + cfg.min_speed_change

    def need_lane(self, agent: _Agent, behaviour: Behaviour, what: str) -> None:
        """Undecided when the map has no lanes or the agent is on none."""
        if not self.index.has_lanes:
            raise TargetUnavailable(agent.track_id, behaviour, "undecided", "the map has no lanes")
        if not agent.on_lane:
            reason = f"it is on no lane at the current step, so its {what} are unknown"
            raise TargetUnavailable(agent.track_id, behaviour, "undecided", reason)

    def ahead(self, agent: _Agent) -> np.ndarray:
        """The agent's lane ahead by the straightest exits, or, off lanes (a pedestrian, a cyclist, a map without
        lanes), the line along its heading."""
        if self.index.has_lanes and agent.on_lane:
            return route(self.index, [agent.here.lane], agent.here.station, agent.reach)
        return straight_line(agent.xy, agent.heading, max(20.0, agent.here.speed * HORIZON_S + 10.0))

    def ways_ahead(self, agent: _Agent) -> list[np.ndarray]:
        """Every way the agent may go: its lane ahead first, then each branch of the next junction."""
        first = self.ahead(agent)
        if not (self.index.has_lanes and self.index.has_connectivity and agent.on_lane):
            return [first]
        return [first] + [
            route(self.index, branch.lanes, agent.here.station, max(agent.reach, branch.exit_at + 25.0))
            for branch in self.junction(agent).branches
        ]


# ---------------------------------------------------------------------------------------------- assessment


def derive_target(
    scenario: Scenario,
    track_id: int,
    behaviour: Behaviour,
    index: MapIndex,
    *,
    other_id: int | None = None,
    config: CounterfactualConfig | None = None,
    gap: float | None = None,
    deceleration: float | None = None,
) -> BehaviourTarget:
    """The target of `behaviour` for `track_id` at the scenario's current step (see the module docstring;
    `TargetContext.target`). Raises `TargetUnavailable` (an InputError) naming the agent, the behaviour and the
    reason where the map gives none: then the behaviour is not feasible there (`feasibility`)."""
    return TargetContext(scenario, index, config).target(track_id, behaviour, other_id, gap, deceleration)


def _target(
    ctx: TargetContext,
    track_id: int,
    behaviour: Behaviour,
    other_id: int | None,
    gap: float | None = None,
    deceleration: float | None = None,
) -> BehaviourTarget:
    """`TargetContext.target`."""
    spec = BEHAVIOURS[behaviour]
    if spec.is_pair and other_id is None:
        raise InputError(f"behaviour {behaviour.value!r} needs another agent", where="target")
    agent = ctx.agent(track_id, behaviour)
    if spec.label is not None and agent.kind not in LABELS_BY_KEY[spec.label].applies_to:
        reason = f"the labelers give {spec.label!r} to no {agent.kind.name.lower()}"
        raise TargetUnavailable(track_id, behaviour, "undecided", reason)
    if spec.is_turn:
        return _turn(ctx, agent, behaviour)
    if spec.is_lane_change:
        return _lane_change(ctx, agent, behaviour, spec.side)  # type: ignore[arg-type]
    if behaviour is Behaviour.STOP:
        return _stop(ctx, agent)
    if behaviour is Behaviour.PULL_OVER:
        return _pull_over(ctx, agent)
    if behaviour in (Behaviour.SPEED_UP, Behaviour.SLOW_DOWN):
        return _speed_change(ctx, agent, behaviour)
    other = ctx.agent(int(other_id), behaviour)  # type: ignore[arg-type]
    if behaviour is Behaviour.FOLLOW:
        path = ctx.ahead(other) if other.on_lane else np.zeros((0, 2))
        return BehaviourTarget(
            track_id, behaviour, path, f"behind @{other_id} along its lane", other_id=other.track_id,
            current_speed=agent.here.speed, other_speed=other.here.speed,
        )  # fmt: skip
    if behaviour is Behaviour.CUT_IN:
        return _cut_in(ctx, agent, other, CUT_IN_GAP_M if gap is None else gap)
    if behaviour is Behaviour.OVERTAKE_CUT_IN:
        return _overtake_cut_in(ctx, agent, other, CUT_IN_GAP_M if gap is None else gap)
    if behaviour is Behaviour.BRAKE_HARD:
        return _brake_hard(ctx, agent, other, BRAKE_HARD_DECELERATION if deceleration is None else deceleration)
    if behaviour is Behaviour.TAILGATE:
        return _tailgate(ctx, agent, other)
    if behaviour is Behaviour.RUN_RED_LIGHT:
        return _run_red_light(ctx, agent, other)
    if behaviour is Behaviour.PULL_OUT:
        return _pull_out(ctx, agent, other)
    return _order(ctx, agent, other, behaviour)


def _gap_behind(index: MapIndex, lead: _Agent, follower: _Agent) -> float | None:
    """The bumper gap (m) from `follower`'s front to `lead`'s rear when `follower` is behind `lead` in its lane:
    heading its way (within 45 degrees), and on one of the pieces of its lane or within 2 m of its line; else None."""
    h = np.array([math.cos(lead.heading), math.sin(lead.heading)])
    d = lead.xy - follower.xy
    along, across = float(d @ h), abs(float(d @ np.array([-h[1], h[0]])))
    if along <= 0.0 or abs(wrap_angle(lead.heading - follower.heading)) > math.radians(45.0):
        return None
    same_lane = lead.on_lane and follower.on_lane and follower.here.lane in _lane_pieces(index, lead.here.lane)
    if not (same_lane or across <= 2.0):
        return None
    return along - 0.5 * (lead.length + follower.length)


def _pair_gap(
    ctx: TargetContext, agent: _Agent, other: _Agent, behaviour: Behaviour, lead: _Agent, where: str
) -> float:
    """The bumper gap between the two when `lead` (one of them) leads the other in its lane within `FOLLOWER_RANGE_M`
    (`_gap_behind`); else `TargetUnavailable` (infeasible) saying where `other` is not (`where`: "behind" it,
    "ahead of" it)."""
    follower = other if lead is agent else agent
    gap = _gap_behind(ctx.index, lead, follower)
    if gap is None or gap > FOLLOWER_RANGE_M:
        why = f"not {where} it in its lane" if gap is None else f"{gap:.0f} m {where} it (at most {FOLLOWER_RANGE_M:g})"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", f"@{other.track_id} is {why}")
    return gap


def _brake_hard(ctx: TargetContext, agent: _Agent, other: _Agent, deceleration: float) -> BehaviourTarget:
    """The agent's lane ahead and the stop that braking at `deceleration` from `BRAKE_HARD_AFTER_S` brings it to,
    the other following within `FOLLOWER_RANGE_M` (Euro NCAP's braking lead vehicle). Infeasible for a deceleration
    outside `BRAKE_HARD_LIMITS`, an agent slower than `BRAKE_HARD_MIN_SPEED`, or no such follower."""
    behaviour, v = Behaviour.BRAKE_HARD, agent.here.speed
    low, high = BRAKE_HARD_LIMITS
    if not low <= deceleration <= high:
        reason = f"braking at {deceleration:g} m/s^2 is outside {low:g} to {high:g} m/s^2 (hard, and what tyres give)"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    if v < BRAKE_HARD_MIN_SPEED:
        reason = f"it is too slow to brake hard ({v:.1f} m/s; at least {BRAKE_HARD_MIN_SPEED:g})"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    gap = _pair_gap(ctx, agent, other, behaviour, lead=agent, where="behind")
    station = v * BRAKE_HARD_AFTER_S + v * v / (2.0 * deceleration)
    return BehaviourTarget(
        agent.track_id,
        behaviour,
        ctx.ahead(agent),
        f"braking at {deceleration:g} m/s^2 from {BRAKE_HARD_AFTER_S:g} s to rest {station:.0f} m ahead, "
        f"@{other.track_id} {gap:.0f} m behind",
        station_of_goal=float(station),
        speed=0.0,
        other_id=other.track_id,
        current_speed=v,
        other_speed=other.here.speed,
        settled_s=BRAKE_HARD_AFTER_S + v / deceleration,
        deceleration=float(deceleration),
    )


def _tailgate(ctx: TargetContext, agent: _Agent, other: _Agent) -> BehaviourTarget:
    """The agent's lane ahead and the station where its gap to the other, keeping its speed, is `TAILGATE_HEADWAY_S`
    of headway, closed `TAILGATE_CLOSING` m/s faster than the other (at least 2 s), then the other's speed.
    Infeasible where the other is not ahead in its lane within `FOLLOWER_RANGE_M`, is slower than
    `TAILGATE_MIN_SPEED`, or the gap cannot be closed within `TAILGATE_WITHIN_S`."""
    behaviour, v_other = Behaviour.TAILGATE, other.here.speed
    gap = _pair_gap(ctx, agent, other, behaviour, lead=other, where="ahead of")
    if v_other < TAILGATE_MIN_SPEED:
        reason = f"@{other.track_id} is too slow to tailgate ({v_other:.1f} m/s; at least {TAILGATE_MIN_SPEED:g})"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    want = TAILGATE_HEADWAY_S * v_other
    within = max(2.0, (gap - want) / TAILGATE_CLOSING)
    if within > TAILGATE_WITHIN_S:
        reason = f"@{other.track_id} is {gap:.0f} m ahead: too far to close to {want:.0f} m in {TAILGATE_WITHIN_S:g} s"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    return BehaviourTarget(
        agent.track_id,
        behaviour,
        ctx.ahead(agent),
        f"{want:.0f} m behind @{other.track_id} ({TAILGATE_HEADWAY_S:g} s at {v_other:.1f} m/s) within {within:.1f} s",
        station_of_goal=float(v_other * within + gap - want),
        speed=float(v_other),
        other_id=other.track_id,
        current_speed=agent.here.speed,
        other_speed=float(v_other),
        settled_s=float(within),
    )


def _lane_beside(
    ctx: TargetContext, agent: _Agent, other: _Agent, behaviour: Behaviour, within: float
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
    theirs = _lane_pieces(index, other.here.lane)
    for lane, station in ahead:
        for side in ("left", "right"):
            beside = index.neighbour_lane(lane, station, side)  # type: ignore[arg-type]
            if beside is not None and beside[0] in theirs:
                return side, beside[0], beside[1]  # type: ignore[return-value]
    reason = f"@{other.track_id} is not in a lane beside its own"
    raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)


def _lead(agent: _Agent, other: _Agent) -> float:
    """How far the agent's centre is ahead of the other's along the other's heading (m)."""
    heading = np.array([math.cos(other.heading), math.sin(other.heading)])
    return float((agent.xy - other.xy) @ heading)


def _cut_in(ctx: TargetContext, agent: _Agent, other: _Agent, gap: float) -> BehaviourTarget:
    """Into the other's lane when it lies beside the agent's (`_lane_beside`) at the agent or at a station of its
    road ahead, from where a change can begin (1 s or 4 m ahead); the `speed` is the average that puts the agent's
    rear `gap` m ahead of the other's front at `CUT_IN_S`, the other keeping its speed, and `station_of_goal` where
    along the path that average takes it by then.
    Infeasible where that needs more than `GO_FIRST_ACCELERATION` could add, or less than standing still."""
    behaviour = Behaviour.CUT_IN
    begin = max(4.0, 1.0 * agent.here.speed)
    side, lane, level = _lane_beside(ctx, agent, other, behaviour, begin + 20.0)
    v, v_other = agent.here.speed, other.here.speed
    lengths = 0.5 * (agent.length + other.length)
    lead = _lead(agent, other)
    speed = (v_other * CUT_IN_S + gap + lengths - lead) / CUT_IN_S
    most = v + 0.5 * GO_FIRST_ACCELERATION * CUT_IN_S
    if speed > most:
        reason = f"it cannot get {gap:g} m ahead of @{other.track_id} in {CUT_IN_S:g} s ({speed:.1f} m/s on average)"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    if speed < 0.0:
        reason = f"it is {lead:.0f} m ahead of @{other.track_id}: too far to cut in {gap:g} m ahead of it"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    return BehaviourTarget(
        agent.track_id,
        behaviour,
        _into_lane(ctx.index, agent, lane, level + begin),
        f"@{other.track_id}'s lane on its {side}, {gap:g} m ahead of it, at {speed:.1f} m/s",
        station_of_goal=float(speed * CUT_IN_S),
        speed=float(speed),
        other_id=other.track_id,
        current_speed=v,
        other_speed=v_other,
        side=side,
        settled_s=CUT_IN_S,
        lead_m=float(gap + lengths),
    )


def _overtake_cut_in(ctx: TargetContext, agent: _Agent, other: _Agent, gap: float) -> BehaviourTarget:
    """Past the other in the agent's own lane, then into the other's lane beside it (`_lane_beside`), settled `gap` m
    ahead of it, the other keeping its speed: the agent speeds up at `GO_FIRST_ACCELERATION` to `OVERTAKE_GAIN`
    faster than the other (or keeps its speed, if faster) until its rear is `OVERTAKE_CLEAR_M` past the other's front
    (not before 1 s), then changes lanes over `LANE_CHANGE_S`, gaining the rest of the gap on the way.
    `station_of_goal` is where it settles, `settled_s` when, `speed` the passing speed. Infeasible where the other is
    slower than `OVERTAKE_MIN_SPEED` (queued traffic is not overtaken), the agent is already ahead of it (a cut-in) or
    more than `FOLLOWER_RANGE_M` behind, it cannot settle by `OVERTAKE_LATEST_S`, or the other's lane runs into a
    junction before it would."""
    behaviour = Behaviour.OVERTAKE_CUT_IN
    side, lane, level = _lane_beside(ctx, agent, other, behaviour, 10.0)
    v, v_other = agent.here.speed, other.here.speed
    if v_other < OVERTAKE_MIN_SPEED:
        reason = f"@{other.track_id} is too slow to overtake ({v_other:.1f} m/s; at least {OVERTAKE_MIN_SPEED:g})"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    lengths = 0.5 * (agent.length + other.length)
    lead = _lead(agent, other)
    if lead - lengths > 0.0:
        reason = f"it is already ahead of @{other.track_id}: that is a cut-in, with no overtake"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    if -lead - lengths > FOLLOWER_RANGE_M:
        reason = f"it is {-lead - lengths:.0f} m behind @{other.track_id} (at most {FOLLOWER_RANGE_M:g})"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    need = gap + lengths - lead  # metres to gain on the other by the time it settles
    top = max(v, v_other + OVERTAKE_GAIN)
    t = np.arange(1, FUTURE_STEPS + 1) * STEP_SECONDS
    travelled = np.cumsum(np.minimum(v + GO_FIRST_ACCELERATION * t, top)) * STEP_SECONDS
    passed = (travelled - v_other * t >= lengths + min(OVERTAKE_CLEAR_M, gap) - lead) & (t >= 1.0 - 1e-9)
    k = int(np.argmax(passed))
    settle = float(t[k]) + LANE_CHANGE_S
    if not passed.any() or settle > OVERTAKE_LATEST_S + 1e-9:
        reason = (
            f"it cannot get {gap:g} m ahead of @{other.track_id} by {OVERTAKE_LATEST_S:g} s "
            f"({need:.0f} m to gain, passing at {top:.1f} m/s)"
        )
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    begin = float(travelled[k])
    goal = max(v_other * settle + need, begin)
    room = ctx.index.distance_to_junction(lane, level) if ctx.index.has_connectivity else math.inf
    if room < goal:
        reason = f"@{other.track_id}'s lane runs into a junction {room:.0f} m ahead, before it could settle there"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    path = _past_then_into_lane(ctx, agent, lane, level, begin, 0.5 * (goal - begin))
    if path is None:
        reason = f"@{other.track_id}'s lane ends before it could change into it"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    return BehaviourTarget(
        agent.track_id,
        behaviour,
        path,
        f"past @{other.track_id} at {top:.1f} m/s, then into its lane on its {side} from "
        f"{settle - LANE_CHANGE_S:.1f} s, {gap:g} m ahead of it by {settle:.1f} s",
        station_of_goal=float(goal),
        speed=float(top),
        other_id=other.track_id,
        current_speed=v,
        other_speed=v_other,
        side=side,
        settled_s=settle,
        lead_m=float(gap + lengths),
    )


def _past_then_into_lane(
    ctx: TargetContext, agent: _Agent, lane: int, level: float, begin: float, across: float
) -> np.ndarray | None:
    """The agent's own lane for `begin` m, then a straight line over `across` m into `lane` (whose station beside
    the agent is `level`), then that lane on: an overtake's way past and back in (None where `lane`, with what it
    leads into, ends before that)."""
    index = ctx.index
    own = route(index, [agent.here.lane], agent.here.station, begin + ROUTE_SPACING)[: int(begin / ROUTE_SPACING) + 1]
    theirs = route(index, [lane], level, begin + across + agent.reach)[int((begin + across) / ROUTE_SPACING) :]
    if len(theirs) < 2:
        return None
    lead_in = resample(np.stack([own[-1], theirs[0]]), ROUTE_SPACING)
    return np.concatenate([own[:-1], lead_in[:-1], theirs])


def _run_red_light(ctx: TargetContext, agent: _Agent, other: _Agent) -> BehaviourTarget:
    """Through a signal showing stop at the current step and across the other's way: the first of the agent's ways
    ahead (`TargetContext.ways_ahead`) that passes within `RED_STOP_LATERAL` of the stop point of such a signal, no
    farther than `RED_LIGHT_REACH_S` at `RED_LIGHT_SPEED` (or its own speed, if faster), and that a way of the other
    agent crosses past it, the other facing no red or amber light before the crossing (it has the right of way); the
    goal is that crossing, passed first, at that speed, as going first (`_order`). Undecided without signals;
    infeasible without such a light and crossing, or where the other gets to the crossing first
    (`_check_going_first`)."""
    behaviour = Behaviour.RUN_RED_LIGHT
    stops = _stop_points(ctx, RED_STATES)
    if stops is None:
        raise TargetUnavailable(agent.track_id, behaviour, "undecided", "the scene has no traffic lights")
    if not len(stops):
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", "no signal shows red at the current step")
    speed = max(agent.here.speed, RED_LIGHT_SPEED)
    reach = speed * RED_LIGHT_REACH_S
    theirs = ctx.ways_ahead(other)
    reason = f"no red light on its way within {reach:.0f} m"
    for path in ctx.ways_ahead(agent):
        found = project_on_polyline(stops, path)
        on_way = (found.distance < RED_STOP_LATERAL) & (found.station > 0.0) & (found.station <= reach)
        if not on_way.any():
            continue
        light = float(found.station[on_way].min())
        arc = arc_lengths(path)
        crossings = [c for c in (_crossing(path, t) for t in theirs) if c is not None and arc[c[0]] > light]
        if not crossings:
            reason = f"@{other.track_id}'s way does not cross its way past the red light {light:.0f} m ahead"
            continue
        i, distance = min(crossings)
        if _red_before(_stop_points(ctx, NOT_GO_STATES), theirs, path[i]):
            reason = f"@{other.track_id} faces a red or amber light too, before the crossing: no right of way to cut"
            continue
        target = BehaviourTarget(
            agent.track_id,
            behaviour,
            path,
            f"through the red light {light:.0f} m ahead at {speed:.1f} m/s, across @{other.track_id}'s way "
            f"{arc[i]:.0f} m ahead, before it",
            station_of_goal=float(arc[i]),
            speed=float(speed),
            other_id=other.track_id,
            conflict=path[i],
            other_eta=distance / max(other.here.speed, 1.0),
            current_speed=agent.here.speed,
            other_speed=other.here.speed,
        )
        _check_going_first(agent, other, target)
        return target
    raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)


def _pull_out(ctx: TargetContext, agent: _Agent, other: _Agent) -> BehaviourTarget:
    """From (nearly) standing onto the other's way ahead of it: the first of the agent's ways (`_pull_out_ways`)
    that comes within `PULL_OUT_MEET_M` of the other's way ahead of the other's front, within `PULL_OUT_REACH_M`
    (one that joins it, running on along it, before one that crosses it); the agent, speeding up as going first does,
    is there `PULL_OUT_GAP_S` before the other gets there at its speed, setting off later (`starts_s`) where the
    other is farther, and drives on at `PULL_OUT_TOP_SPEED` or the other's speed. Infeasible for an agent moving
    faster than `PULL_OUT_MAX_SPEED`, on the other's way already (within `PULL_OUT_OFF_WAY_M`), with no such meeting,
    or with a red light on its way before it (that is running the light); for an other slower than
    `PULL_OUT_OTHER_MIN_SPEED`, there later than `PULL_OUT_LATEST_S`, or too close to be there less than
    `PULL_OUT_MIN_GAP_S` after the agent."""
    behaviour, v, v_other = Behaviour.PULL_OUT, agent.here.speed, other.here.speed
    if agent.kind not in (AgentType.VEHICLE, AgentType.CYCLIST):
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", "only vehicles and cyclists pull out")
    if v > PULL_OUT_MAX_SPEED:
        reason = f"it is moving at {v:.1f} m/s: a pull-out starts from standing or a crawl "
        reason += f"(at most {PULL_OUT_MAX_SPEED:g})"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    if v_other < PULL_OUT_OTHER_MIN_SPEED:
        reason = f"@{other.track_id} is too slow to pull out in front of ({v_other:.1f} m/s; at least "
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason + f"{PULL_OUT_OTHER_MIN_SPEED:g})")
    theirs = ctx.ahead(other)
    if float(project_on_polyline(agent.xy, theirs).distance) <= PULL_OUT_OFF_WAY_M:
        reason = f"it is on @{other.track_id}'s way already: nothing to pull out of"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    clear = 0.5 * (agent.length + other.length) + 2.0  # its centre this far ahead of the other's, at least
    meetings = [m for m in (_meeting(path, theirs) for path in _pull_out_ways(ctx, agent, theirs)) if m is not None]
    meetings = [m for m in meetings if m[1] <= PULL_OUT_REACH_M and m[2] > clear]
    if not meetings:
        reason = f"none of its ways meets @{other.track_id}'s way ahead of it within {PULL_OUT_REACH_M:g} m"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    path, there, station, joins = min(meetings, key=lambda m: (not m[3], m[1]))
    if _red_on_way(ctx, path, there):
        reason = f"its way shows red before @{other.track_id}'s: going on is running the red light"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    need = _time_to_cover(there, v)
    other_there = (station - 0.5 * other.length) / max(v_other, 1e-6)
    if other_there > PULL_OUT_LATEST_S:
        reason = f"@{other.track_id} is {other_there:.1f} s from where it would pull out "
        reason += f"(at most {PULL_OUT_LATEST_S:g})"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    if other_there - need < PULL_OUT_MIN_GAP_S:
        reason = f"@{other.track_id} gets to where it would pull out in {other_there:.1f} s; it needs {need:.1f} s"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    starts = max(other_there - need - PULL_OUT_GAP_S, 0.0)
    how = "into" if joins else "across"
    return BehaviourTarget(
        agent.track_id,
        behaviour,
        path,
        f"out {how} @{other.track_id}'s way {there:.0f} m ahead from {starts:.1f} s, there by {starts + need:.1f} s, "
        f"{other_there - starts - need:.1f} s before it",
        station_of_goal=float(there),
        speed=float(min(PULL_OUT_TOP_SPEED, v_other)),
        other_id=other.track_id,
        conflict=point_at(path, there),
        other_eta=float(other_there),
        current_speed=v,
        other_speed=v_other,
        settled_s=float(starts + need),
        lead_m=float(clear) if joins else None,
        starts_s=float(starts),
    )


def _pull_out_ways(ctx: TargetContext, agent: _Agent, theirs: np.ndarray) -> list[np.ndarray]:
    """The ways a pull-out may take: on a lane, its ways by the lane graph (`TargetContext.ways_ahead`); off lanes (a
    driveway, a car park, the kerb), a straight line onto the other's way `theirs`, meeting it as far past the point
    beside the agent as the agent is from it (at least 6 m), then along it, where the agent faces that point."""
    if ctx.index.has_lanes and agent.on_lane:
        return ctx.ways_ahead(agent)
    beside = project_on_polyline(agent.xy, theirs)
    station = float(beside.station) + max(6.0, float(beside.distance))
    entry = point_at(theirs, station)
    to_entry = entry - agent.xy
    facing = np.array([math.cos(agent.heading), math.sin(agent.heading)])
    if float(to_entry @ facing) <= 0.0:
        return []
    on = theirs[arc_lengths(theirs) > station]
    lead_in = resample(np.stack([agent.xy, entry]), ROUTE_SPACING)
    return [np.concatenate([lead_in[:-1], entry[None], on])]


def _meeting(path: np.ndarray, theirs: np.ndarray) -> tuple[np.ndarray, float, float, bool] | None:
    """Where `path` first comes within `PULL_OUT_MEET_M` of the other's way `theirs`: (path, the station along
    `path` there, the station along `theirs`, whether `path` joins it, running on within that of it 5 m later);
    None where it never does."""
    if len(path) < 2:
        return None
    found = project_on_polyline(path, theirs)
    near = np.flatnonzero(found.distance < PULL_OUT_MEET_M)
    if not near.size:
        return None
    i = int(near[0])
    arc = arc_lengths(path)
    later = int(np.searchsorted(arc, arc[i] + 5.0))
    joins = later < len(path) and bool(found.distance[later] < PULL_OUT_MEET_M)
    return path, float(arc[i]), float(found.station[i]), joins


def _stop_points(ctx: TargetContext, states: Iterable[TrafficLightState]) -> np.ndarray | None:
    """The stop points [K, 2] of the signals showing one of `states` at the current step (none: [0, 2]); None where
    the scene has no signals."""
    lights, c = ctx.scenario.traffic_lights, ctx.scenario.current_index
    if lights is None or lights.num_lanes == 0:
        return None
    showing = np.isin(lights.states[c], [int(s) for s in states]) & lights.valid[c]
    return np.asarray(lights.stop_points)[showing, :2]


def _red_on_way(ctx: TargetContext, path: np.ndarray, station: float) -> bool:
    """Whether the stop point of a signal showing stop at the current step lies on `path` (within
    `RED_STOP_LATERAL`) before `station`."""
    stops = _stop_points(ctx, RED_STATES)
    if stops is None or not len(stops):
        return False
    found = project_on_polyline(stops, path)
    return bool(((found.distance < RED_STOP_LATERAL) & (found.station < station)).any())


def _red_before(stops: np.ndarray, ways: list[np.ndarray], point: np.ndarray) -> bool:
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


def _turn(ctx: TargetContext, agent: _Agent, behaviour: Behaviour) -> BehaviourTarget:
    """The nearest branch of the next junction in the asked direction: the lanes to it, the junction lanes, and past
    the exit; the goal station lies 5 m past the junction."""
    index = ctx.index
    ctx.need_lane(agent, behaviour, "junction directions")
    if not index.has_connectivity:
        reason = "the map has no lane connectivity to follow its lane to a junction"
        raise TargetUnavailable(agent.track_id, behaviour, "undecided", reason)
    reach = agent.search
    found = ctx.junction(agent)
    if not found.branches:
        if found.ends:
            reason = f"its lanes end within {reach:.0f} m with no junction (the map stops there)"
            raise TargetUnavailable(agent.track_id, behaviour, "undecided", reason)
        if behaviour is Behaviour.GO_STRAIGHT:
            reason = f"no junction within {reach:.0f} m: going straight is its road"
            raise TargetUnavailable(agent.track_id, behaviour, "undecided", reason)
        raise TargetUnavailable(
            agent.track_id, behaviour, "infeasible", f"no junction within {reach:.0f} m along its lanes"
        )
    directions = {b: branch_direction(b.turn, ctx.config) for b in found.branches}
    mine = [b for b in found.branches if directions[b] is behaviour]
    if not mine:
        words = {
            Behaviour.TURN_LEFT: "left turn",
            Behaviour.GO_STRAIGHT: "straight on",
            Behaviour.TURN_RIGHT: "right turn",
        }
        allowed = ", ".join(w for b, w in words.items() if b in directions.values()) or "only U-turns or bends"
        reason = f"no {words[behaviour]} from its lane at the next junction (it allows: {allowed})"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    branch = min(mine, key=lambda b: b.exit_at)
    goal = branch.exit_at + 5.0
    path = route(index, branch.lanes, agent.here.station, max(agent.reach, goal + 25.0))
    return BehaviourTarget(
        agent.track_id,
        behaviour,
        path,
        f"the {BEHAVIOURS[behaviour].manoeuvre} branch of the next junction, its exit {branch.exit_at:.0f} m ahead",
        station_of_goal=goal,
        current_speed=agent.here.speed,
    )


def _lane_change(ctx: TargetContext, agent: _Agent, behaviour: Behaviour, side: Side) -> BehaviourTarget:
    """The neighbour lane on `side` (`MapIndex.neighbour_lane`, the labelers' definition) at the first station of
    the agent's road ahead from where a change can begin (1 s or 4 m ahead), where that lane runs on without a
    junction long enough for a change begun there to settle in it (`LANE_CHANGE_S` at the agent's speed, at least
    `LANE_CHANGE_MIN_M`: the labelers count no change into a junction lane)."""
    index = ctx.index
    ctx.need_lane(agent, behaviour, "neighbour lanes")
    if index.neighbor_source == "none":
        raise TargetUnavailable(agent.track_id, behaviour, "undecided", "the map has no lane neighbour information")
    begin = max(4.0, 1.0 * agent.here.speed)
    room_needed = max(LANE_CHANGE_MIN_M, LANE_CHANGE_S * agent.here.speed)
    ahead = ctx.stations(agent)
    if not ahead:
        reason = "it is inside a junction, where lanes have no neighbours"
        raise TargetUnavailable(agent.track_id, behaviour, "undecided", reason)
    cramped = False
    for point in ahead:
        if point.distance < begin:
            continue
        found = index.neighbour_lane(point.lane, point.station, side)
        if found is None or index.is_junction[found[0]]:
            continue
        lane, station = found
        room = index.distance_to_junction(lane, station) if index.has_connectivity else math.inf
        if round(point.distance + room - begin, 2) < round(room_needed, 2):  # to the centimetre
            cramped = True  # the lane beside it runs into a junction before a change could settle in it
            continue
        path = _into_lane(index, agent, lane, station)
        return BehaviourTarget(
            agent.track_id,
            behaviour,
            path,
            f"the lane on its {side}, from {point.distance:.0f} m ahead",
            current_speed=agent.here.speed,
            side=side,
            joins_m=float(np.linalg.norm(index.point_at(lane, station) - agent.xy)),
        )
    reason = f"no lane on its {side} along its road (within {agent.search:.0f} m)"
    if cramped:
        reason = f"the lane on its {side} runs into a junction before a change could settle in it"
    raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)


def _into_lane(index: MapIndex, agent: _Agent, lane: int, station: float) -> np.ndarray:
    """The agent's way into `lane` at `station` (a lane change, a cut-in): a straight lead-in from where it is, then
    the lane on."""
    path = route(index, [lane], station, agent.reach)
    lead_in = resample(np.stack([agent.xy, path[0]]), ROUTE_SPACING)
    return np.concatenate([lead_in[:-1], path])


def _stop(ctx: TargetContext, agent: _Agent) -> BehaviourTarget:
    """A stop on the way ahead where comfortable braking brings the agent to rest; at a stop line (the start of the
    next junction or a signal's stop point) or before a crosswalk when one lies a little beyond that, but no farther
    than the agent gets braking evenly over 7 s."""
    index = ctx.index
    path = ctx.ahead(agent)
    v = agent.here.speed
    comfort = v * v / (2 * COMFORT_DECELERATION) + 0.5 * agent.length
    latest = max(comfort, 0.5 * v * 7.0)
    reason, station = f"where braking at {COMFORT_DECELERATION:g} m/s^2 brings it to rest", comfort
    marks: list[tuple[float, str]] = []
    if agent.on_lane and index.has_connectivity and not index.is_junction[agent.here.lane]:
        marks.append((index.distance_to_junction(agent.here.lane, agent.here.station) - 1.0, "at the stop line"))
    lights = ctx.scenario.traffic_lights
    if lights is not None and len(lights.stop_points):
        found = project_on_polyline(np.asarray(lights.stop_points)[:, :2], path)
        marks += [
            (float(s) - 1.0, "at the signal's stop line")
            for s, d in zip(found.station, found.distance, strict=True)
            if d < 2.5
        ]
    crossing = index.in_crosswalk(path) if index.has_crosswalks else np.zeros(len(path), bool)
    if crossing.any():
        marks.append((float(arc_lengths(path)[int(np.argmax(crossing))]) - 2.0, "before the crosswalk"))
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
        speed=0.0,
        current_speed=v,
    )


def _pull_over(ctx: TargetContext, agent: _Agent) -> BehaviourTarget:
    """The agent moves in the lane next to the kerb on its right (the rightmost or only lane) with room to stop
    comfortably before the next junction (the labeler does not call a stop at a junction a pull-over): the lane ahead
    shifted to the right, to the kerb (`kerb_distance`, less half the width and `KERB_CLEARANCE`, at least 0.8 m off
    the centre, but never nearer the edge than `KERB_MIN_CLEARANCE`) or half a lane where the map has no road
    edges, and a stop where gentle braking brings it to rest."""
    index, behaviour = ctx.index, Behaviour.PULL_OVER
    if not ctx.moving(agent):
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", "it is (nearly) stopped at the current step")
    ctx.need_lane(agent, behaviour, "lane position")
    position = index.lane_position(agent.here.lane, agent.here.station)
    if position == "unknown":
        reason = (
            "the map has no lane neighbour information"
            if index.neighbor_source == "none"
            else "it is inside a junction, where lanes have no neighbours"
        )
        raise TargetUnavailable(agent.track_id, behaviour, "undecided", reason)
    if position not in ("rightmost", "single"):
        reason = "a lane lies on its right: it is not in the lane next to the kerb"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    v = agent.here.speed
    room = v**2 / (2 * COMFORT_DECELERATION) + ctx.config.heuristics.pull_over_junction_distance
    junction = index.distance_to_junction(agent.here.lane, agent.here.station) if index.has_connectivity else math.inf
    if junction >= room:
        lane_path = ctx.ahead(agent)
        stop = max(v * v / (2 * PULL_OVER_DECELERATION), 2.0 * v, 8.0)
        stop = min(stop, max(0.5 * v * 5.5, 8.0))
        begin, where = min(max(0.3 * stop, 3.0), stop), ""
    else:
        near = f"the next junction is {junction:.0f} m ahead, too close to stop at the kerb before it"
        lane_path, stop, begin, why_not = _kerb_past_junction(ctx, agent)
        if why_not:
            raise TargetUnavailable(agent.track_id, behaviour, "infeasible", f"{near}, and {why_not}")
        where = f" past the junction {junction:.0f} m ahead"
    point = point_at(lane_path, stop)
    offset, reason = 1.2, "half a lane to its right (the map has no road edges)"
    if index.has_road_edges:
        k = min(int(stop / ROUTE_SPACING), len(lane_path) - 2)
        d = lane_path[k + 1] - lane_path[k]
        kerb = kerb_distance(index, point, np.array([d[1], -d[0]]) / max(float(np.linalg.norm(d)), 1e-9))
        if kerb is None:
            reason = f"half a lane to its right (no road edge within {KERB_SEARCH_M:.0f} m of its lane)"
        else:
            beside = kerb - 0.5 * agent.width  # how far its centre can move right before its side meets the edge
            offset = float(min(np.clip(beside - KERB_CLEARANCE, 0.8, 3.0), beside - KERB_MIN_CLEARANCE))
            if offset < ctx.config.heuristics.pull_over_min_lane_offset:
                reason = f"the road edge is {kerb:.1f} m to its right: no room beside its lane to pull over"
                raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
            reason = f"the kerb {kerb:.1f} m to its right"
    arc = arc_lengths(lane_path)
    shift = offset * np.clip((arc - begin) / max(stop - begin, 1.0), 0.0, 1.0)
    tangent = np.gradient(lane_path, axis=0)
    tangent /= np.maximum(np.linalg.norm(tangent, axis=1, keepdims=True), 1e-9)
    right = np.stack([tangent[:, 1], -tangent[:, 0]], -1)
    return BehaviourTarget(
        agent.track_id,
        behaviour,
        lane_path + shift[:, None] * right,
        f"a stop {stop:.0f} m ahead{where}, {reason}",
        station_of_goal=float(stop),
        speed=0.0,
        current_speed=v,
    )


def _kerb_past_junction(ctx: TargetContext, agent: _Agent) -> tuple[np.ndarray, float, float, str]:
    """The next kerb a driver would use when the one before the junction is too near: through the junction on its
    straightest branch into a kerb lane (the rightmost or only one) and `KERB_PAST_JUNCTION_M` past its exit, with
    room before the lane's own next junction, reached braking at no more than `COMFORT_DECELERATION` and within the
    horizon (driving on at its speed, then braking at `PULL_OVER_DECELERATION`). Gives the path, the stop station,
    where the move toward the kerb begins, and why there is no such kerb (empty when there is)."""
    index, v = ctx.index, agent.here.speed
    branches = ctx.junction(agent).branches
    if not branches:
        return np.zeros((0, 2)), 0.0, 0.0, "no way through it on the map"
    branch = min(branches, key=lambda b: (abs(b.turn), b.exit_at))
    exits = [e for e in index.exits[branch.lanes[-1]] if not index.is_junction[e]]
    if not exits:
        return np.zeros((0, 2)), 0.0, 0.0, "its way through the junction leads into no road lane"
    lane = exits[0]
    if index.lane_position(lane, 0.0) not in ("rightmost", "single"):
        return np.zeros((0, 2)), 0.0, 0.0, "its lane past the junction has a lane on its right"
    stop = max(branch.exit_at + KERB_PAST_JUNCTION_M, v * v / (2 * COMFORT_DECELERATION))
    braking = min(v * v / (2 * PULL_OVER_DECELERATION), stop)
    if (stop - braking) / max(v, 0.1) + 2 * braking / max(v, 0.1) > HORIZON_S:
        why = f"the kerb past it ({stop:.0f} m ahead) is beyond its reach in {HORIZON_S:g} s"
        return np.zeros((0, 2)), 0.0, 0.0, why
    beyond = index.distance_to_junction(lane, 0.0) - (stop - branch.exit_at)
    if beyond < ctx.config.heuristics.pull_over_junction_distance:
        return np.zeros((0, 2)), 0.0, 0.0, "the road past it reaches another junction too soon"
    path = route(index, (*branch.lanes, lane), agent.here.station, max(agent.reach, stop + 20.0))
    return path, stop, branch.exit_at + 2.0, ""


def stop_after(target: BehaviourTarget) -> BehaviourTarget:
    """A manoeuvre's target (a turn or a lane change) and then a stop past it: along its path, `STOP_AFTER_M` past
    where the manoeuvre is done (a turn: its goal past the junction's exit; a lane change: where its lead-in joins the
    new lane, and no sooner than its steering holds it there, `LANE_CHANGE_DONE_S` at its speed), and no nearer than
    braking at `COMFORT_DECELERATION` brings it to rest; standing (`settled_s`) once it gets there driving on at its
    speed (at least `STOP_AFTER_MIN_SPEED`) and then braking at that deceleration, which must be by
    `STOP_AFTER_BY_S`; else `TargetUnavailable` (infeasible)."""
    spec = BEHAVIOURS[target.behaviour]
    v = target.current_speed
    if spec.is_turn and target.station_of_goal is not None:
        done, what = target.station_of_goal, "the junction"
    elif spec.is_lane_change:
        done, what = max(target.joins_m or 0.0, LANE_CHANGE_DONE_S * v, LANE_CHANGE_MIN_M), "its lane change"
    else:
        raise InputError(f"a stop after {target.behaviour.value} is not a sequence LangTraj steers", where="target")
    stop = max(done + STOP_AFTER_M, v * v / (2 * COMFORT_DECELERATION) + 0.5)  # and half a metre to come to rest
    length = float(arc_lengths(target.path)[-1]) if len(target.path) >= 2 else 0.0
    if stop > length:
        reason = f"its way past {what} ends before a stop {stop:.0f} m ahead"
        raise TargetUnavailable(target.track_id, target.behaviour, "infeasible", reason)
    cruise = max(v, STOP_AFTER_MIN_SPEED)
    braking = min(cruise * cruise / (2 * COMFORT_DECELERATION), stop)  # the metres it brakes over
    standing = (stop - braking) / cruise + 2 * braking / cruise
    if standing > STOP_AFTER_BY_S:
        reason = f"a stop past {what} ({stop:.0f} m ahead) is beyond its reach in {STOP_AFTER_BY_S:g} s"
        raise TargetUnavailable(target.track_id, target.behaviour, "infeasible", reason)
    return replace(
        target,
        reason=f"{target.reason}, then a stop {stop:.0f} m ahead",
        station_of_goal=float(stop),
        speed=0.0,
        settled_s=float(standing),
    )


def kerb_distance(index: MapIndex, point: np.ndarray, direction: np.ndarray) -> float | None:
    """How far from `point` along the unit `direction` the first road edge lies (m; None: none within
    `KERB_SEARCH_M`): sphere tracing, each step the distance to the nearest edge, so the ray never passes one."""
    travelled = 0.0
    for _ in range(64):  # a ray grazing an edge crawls: after 64 steps it is within centimetres of one
        gap = float(index.distance_to_road_edge(point + travelled * direction, KERB_SEARCH_M)[0])
        if not math.isfinite(gap):
            return None
        if gap < 0.02:
            return travelled
        travelled += gap
        if travelled > KERB_SEARCH_M:
            return None
    return travelled


def _speed_change(ctx: TargetContext, agent: _Agent, behaviour: Behaviour) -> BehaviourTarget:
    """The way ahead at 3 m/s more or less (slowing down keeps at least 35 % of the speed; it needs the agent to
    move)."""
    v = agent.here.speed
    if behaviour is Behaviour.SLOW_DOWN and not ctx.moving(agent):
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", "it is (nearly) stopped at the current step")
    speed = v + SPEED_CHANGE if behaviour is Behaviour.SPEED_UP else max(v - SPEED_CHANGE, 0.35 * v)
    return BehaviourTarget(
        agent.track_id, behaviour, ctx.ahead(agent), f"its way ahead at {speed:.1f} m/s", speed=speed,
        current_speed=v,
    )  # fmt: skip


def _lane_pieces(index: MapIndex, lane: int, hops: int = 3) -> set[int]:
    """`lane` and the non-junction lanes up to `hops` before and after it: the pieces of one lane of a road."""
    found, frontier = {lane}, {lane}
    for _ in range(hops):
        frontier = {n for x in frontier for n in (*index.exits[x], *index.entries[x]) if not index.is_junction[n]}
        frontier -= found
        found |= frontier
    return found


def _crossing(mine: np.ndarray, theirs: np.ndarray) -> tuple[int, float] | None:
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


def _order(ctx: TargetContext, agent: _Agent, other: _Agent, behaviour: Behaviour) -> BehaviourTarget:
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
        crossings = [c for c in (_crossing(path, t) for t in theirs) if c is not None]
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
        _check_going_first(agent, other, target)
    return target


def _check_going_first(agent: _Agent, other: _Agent, target: BehaviourTarget) -> None:
    """Raise where the agent cannot get to the crossing first (see `_order`)."""
    if target.conflict is None or target.station_of_goal is None or target.other_eta is None:
        raise TargetUnavailable(agent.track_id, target.behaviour, "undecided", target.reason)
    if other.kind != AgentType.VEHICLE and np.linalg.norm(other.xy - target.conflict) < 3.0:
        reason = f"@{other.track_id} is already crossing its path"
        raise TargetUnavailable(agent.track_id, target.behaviour, "infeasible", reason)
    need = _time_to_cover(target.station_of_goal, target.current_speed)
    if need + GO_FIRST_MARGIN_S >= target.other_eta:
        reason = f"@{other.track_id} gets to the crossing in {target.other_eta:.1f} s; it needs {need:.1f} s"
        raise TargetUnavailable(agent.track_id, target.behaviour, "infeasible", reason)


def _time_to_cover(distance: float, speed: float) -> float:
    """Seconds to cover `distance` m from `speed`, speeding up at `GO_FIRST_ACCELERATION` to the top speed."""
    a, top = GO_FIRST_ACCELERATION, max(GO_FIRST_TOP_SPEED, speed)
    ramp = (top - speed) / a
    ramp_distance = speed * ramp + 0.5 * a * ramp**2
    if distance <= ramp_distance:
        return (-speed + math.sqrt(speed**2 + 2 * a * distance)) / a
    return ramp + (distance - ramp_distance) / top
