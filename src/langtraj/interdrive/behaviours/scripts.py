"""Manoeuvres a behaviour executes exactly rather than steers toward, as a scenario's scripted actor does
(OpenSCENARIO's SpeedAction and LaneChangeAction; CARLA's ScenarioRunner): a braking lead at the asked deceleration in
its lane, a cut-in settling the asked gap ahead of the other agent wherever that agent drives. A `Script` plans its
agent's actions (acceleration, yaw rate) block by block from the agents' states at a replan; the simulation puts them
in the agent's plans before guidance and selection see them (`sim.candidates`), and the model drives the agent again
where a script gives none. Plain numpy: the layer below guidance (docs/simulation.md, 'Scripted manoeuvres').
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from langtraj.car_following import idm_interaction
from langtraj.polylines import arc_lengths, point_at, project_on_polyline, ray_meets_polyline

LOOK_AHEAD_S = 1.0
"""Pure pursuit's look-ahead keeping a lane (s of speed, at least `LOOK_AHEAD_MIN_M`)."""
LOOK_AHEAD_MIN_M = 4.0


@dataclass(frozen=True)
class ScriptState:
    """What a script plans from: its agent's and the other agent's state (x, y, heading, speed; one frame) and the
    other's acceleration (m/s^2), the target's path [P, 2] in that frame, the seconds since the behaviour started,
    the dynamics' blocks (`count` actions of `per_action` steps of `dt` s, yaw rate within +-`max_yaw_rate`), and
    the agent's own lane and the lane it moves into [M, 2] where the target has them (None: none; the path then), its
    size and the traffic around it."""

    agent: np.ndarray
    other: np.ndarray | None
    other_accel: float
    path: np.ndarray
    elapsed_s: float
    count: int
    per_action: int
    dt: float
    max_yaw_rate: float
    own_lane: np.ndarray | None = None
    new_lane: np.ndarray | None = None
    size: tuple[float, float] = (4.5, 2.0)
    """The agent's length and width (m)."""
    other_size: tuple[float, float] | None = None
    """The other agent's length and width (m); None: the agent's own (`other_box`)."""
    traffic: np.ndarray | None = None
    """Every other agent but the other [K, 6] (x, y, heading, speed, length, width; same frame), which the agent keeps
    off ahead of it (`keep_behind`); None: none."""
    memory: dict[str, Any] = field(default_factory=dict)
    """What the script decided or saw at the steps executed so far (one per agent and rollout, kept by the simulation):
    a decision its first action takes (a cut-in that has begun to move across goes on across), or the other's way so
    far (a follower's `trail`)."""

    @property
    def other_box(self) -> tuple[float, float]:
        """The other agent's length and width (m), the agent's own where the state does not say."""
        return self.other_size if self.other_size is not None else self.size


class Script(ABC):
    """A manoeuvre executed exactly (see the module)."""

    @abstractmethod
    def plan(self, now: ScriptState) -> np.ndarray:
        """Actions [count, 2] (acceleration m/s^2, yaw rate rad/s) from `now`; NaN where the model's stand."""


def pursuit_rate(
    x: float, y: float, heading: float, speed: float, path: np.ndarray, ahead: float, most: float
) -> float:
    """The yaw rate (rad/s, within +-`most`) pure pursuit steers to reach the point `ahead` m along `path` past the
    agent's nearest point."""
    station = float(project_on_polyline(np.array([[x, y]]), path).station[0])
    goal = point_at(path, min(station + ahead, float(arc_lengths(path)[-1])))
    bearing = math.atan2(goal[1] - y, goal[0] - x) - heading
    alpha = math.atan2(math.sin(bearing), math.cos(bearing))
    curvature = 2.0 * math.sin(alpha) / max(math.hypot(goal[0] - x, goal[1] - y), 1e-3)
    return float(np.clip(curvature * max(speed, 0.5), -most, most))


def unicycle_step(state: list[float], accel: float, rate: float, dt: float) -> None:
    """One step of the unicycle dynamics (`model.dynamics.Unicycle`), in place on (x, y, heading, speed): speed (at
    least 0), heading, then position."""
    state[3] = max(state[3] + accel * dt, 0.0)
    state[2] += rate * dt
    state[0] += state[3] * math.cos(state[2]) * dt
    state[1] += state[3] * math.sin(state[2]) * dt


KEEP_BEHIND = {"max_accel": 2.5, "comfortable_decel": 3.0, "time_headway": 1.0, "min_gap": 2.0}
"""The IDM a scripted agent keeps off the traffic ahead in its lane with (`keep_behind`): an assertive driver's (1 s of
headway, 2 m standing), whose free road is its script's."""
SCRIPT_HARD_BRAKE = 6.0
"""The hardest a scripted agent brakes for traffic ahead of it (m/s^2)."""
KEEP_BEHIND_AHEAD_M = 80.0
"""How far ahead along its lane (m) a scripted agent looks for traffic."""
KEEP_BEHIND_MARGIN_M = 0.3
"""An agent is in a scripted agent's lane ahead when its centre is within the two half widths and this of the lane
(m), as the IDM planner's corridor (`IDMConfig.corridor_margin`)."""


def keep_behind(accel: float, state: list[float], lane: np.ndarray, now: ScriptState, traffic: np.ndarray) -> float:
    """`accel` (m/s^2) limited by the IDM (`KEEP_BEHIND`, free road at its largest acceleration) toward the nearest
    agent of `traffic` [K, 6] (`ScriptState.traffic`, as it is at this step) in `lane` ahead of the agent: a scripted
    adversary drives its manoeuvre, never through the cars in front of it (the issue's 'adversaries that drive like
    drivers'); at least -`SCRIPT_HARD_BRAKE`."""
    if not len(traffic) or len(lane) < 2:
        return accel
    found = project_on_polyline(np.concatenate([np.array([state[:2]]), traffic[:, :2]]), lane)
    ahead = found.station[1:] - found.station[0]
    corridor = 0.5 * (now.size[1] + traffic[:, 5]) + KEEP_BEHIND_MARGIN_M
    inside = (ahead > 0.0) & (ahead < KEEP_BEHIND_AHEAD_M) & (found.distance[1:] <= corridor)
    if not inside.any():
        return accel
    gaps = ahead[inside] - 0.5 * (now.size[0] + traffic[inside, 4])
    along = traffic[inside, 3] * np.cos(traffic[inside, 2] - state[2])
    limit = KEEP_BEHIND["max_accel"] + float(idm_interaction(state[3], gaps, along, **KEEP_BEHIND).min())
    return float(max(min(accel, limit), -SCRIPT_HARD_BRAKE))


SLOT_MARGIN_M = 2.0
"""The least bumper gap (m) a lane change leaves to the traffic in the lane it moves into, ahead and behind
(`slot_free`), besides a second of the follower's closing speed."""


def slot_free(state: list[float], lane: np.ndarray, now: ScriptState, traffic: np.ndarray) -> bool:
    """Whether the agent's place in `lane` beside where it is now is free of `traffic` [K, 6]: no one in the lane within
    `SLOT_MARGIN_M` of its bumpers, nor a follower there closing the gap within a second (a driver's gap acceptance,
    as MOBIL's safety criterion; the other agent a cut-in is toward is the script's own business)."""
    if not len(traffic) or len(lane) < 2:
        return True
    found = project_on_polyline(np.concatenate([np.array([state[:2]]), traffic[:, :2]]), lane)
    ahead = found.station[1:] - found.station[0]
    inside = found.distance[1:] <= 0.5 * (now.size[1] + traffic[:, 5]) + KEEP_BEHIND_MARGIN_M
    bumpers = np.abs(ahead) - 0.5 * (now.size[0] + traffic[:, 4])
    closing = np.where(ahead < 0, traffic[:, 3] * np.cos(traffic[:, 2] - state[2]) - state[3], 0.0)
    return not bool((inside & (bumpers < SLOT_MARGIN_M + np.maximum(closing, 0.0))).any())


def with_other(traffic: np.ndarray, other: list[float] | None, now: ScriptState) -> np.ndarray:
    """`traffic` [K, 6] and the other agent as it is: a scripted agent that finds the other in its way ahead (a
    runner's other got there first; a cut-in starts behind it) keeps off it like any car, rather than driving into
    it."""
    if other is None:
        return traffic
    return np.concatenate([traffic, np.array([[*other[:4], *now.other_box]])])


def traffic_at(now: ScriptState, action: int) -> np.ndarray:
    """`now.traffic` [K, 6] at the start of its `action`-th action, each agent at constant speed and heading (none:
    [0, 6])."""
    if now.traffic is None:
        return np.zeros((0, 6))
    seconds, out = action * now.per_action * now.dt, now.traffic.copy()
    out[:, 0] += now.traffic[:, 3] * np.cos(now.traffic[:, 2]) * seconds
    out[:, 1] += now.traffic[:, 3] * np.sin(now.traffic[:, 2]) * seconds
    return out


CUT_IN_LOOK_AHEAD_S = 1.2
"""A scripted cut-in's pure-pursuit look-ahead (s of speed, at least `CUT_IN_LOOK_AHEAD_MIN_M`): its centre into the
lane about 1.5 s after it turns, settled in about 2.5 s, as drivers change lanes, not a swerve (at 2 s and at least
10 m the change took 3.5-4 s on held-out scenes, and a follower slowing meanwhile opened the gap)."""
CUT_IN_LOOK_AHEAD_MIN_M = 2.5
"""At a crawl a cut-in turns more sharply, as drivers do in a queue: with 4 m, one at 2 m/s behind a cautious ego took
5 s to move across, 16-19 degrees off the lane throughout, and never settled within a scenario."""
CUT_IN_GAP_GAIN = 1.0
"""Per second squared: the acceleration per metre a scripted cut-in is short of (or past) its lead on the other."""
CUT_IN_SPEED_GAIN = 1.6
"""Per second: the acceleration per m/s the cut-in is slower (or faster) than the other (with `CUT_IN_GAP_GAIN`: a
damping ratio of 0.8, within 2 m of its lead in about 3 s where the acceleration limits allow; at 0.4 and 1.0 it
took 8 s, longer than a scenario)."""
CUT_IN_ACCELERATIONS = (-3.5, 2.5)
"""What a scripted cut-in may brake and accelerate (m/s^2) to keep its lead, on top of the other's own braking
(`_keep_lead`): firm, not an emergency."""
CUT_IN_CLEAR_M = 5.5
"""How far ahead of the other's centre a cut-in's centre gets before it moves across (two car lengths' halves and a
metre: its rear past the other's front): it pulls in ahead of the other, never across it from beside (a side-swipe)."""


CUT_IN_GAP_SLACK_M = 2.0
"""How much nearer than its lead a cut-in may be when it enters the lane (m, `CUT_IN_ENTRY_S`): it pulls in at about
the asked gap, not the first moment it could (3 m ahead of a follower's bumper made the planners brake hard and the
gap it settled at 20-27 m)."""
CUT_IN_FAR_SLACK_M = 1.5
"""How much farther than its lead a cut-in may be when it enters the lane (m, `CUT_IN_ENTRY_S`): a follower that brakes
for the move opens the gap meanwhile (at 5 m on the lead when it turned, a held-out cut-in entered at a 13.4 m gap
where 10 were asked)."""
CUT_IN_CROSSING_MIN_MPS = 3.0
"""The least speed (m/s) a cut-in keeps while it moves across: a lane change at a crawl does not end within a scenario
(behind a cautious ego at 2 m/s, a validation cut-in slowed to 0.7-1.6 m/s, turned 26-35 degrees off the lane, and
was still moving across at 8 s)."""
CUT_IN_ALIGNED = math.radians(5.0)
"""Until its heading is this near its way's (rad), a cut-in in the lane is still moving across (at a crawl it would
never straighten: its yaw rate goes with its speed)."""
CUT_IN_IN_LANE_M = 0.7
"""How near its path (m) a cut-in is once in the lane: from then (and its settling time) it drives on slower."""
CUT_IN_MATCHED_MPS = 3.0
"""How much faster or slower than the other (m/s) a cut-in may be when it enters the lane (`CUT_IN_ENTRY_S` on): it
first matches the other's speed, so that the gap it enters at is the one it holds (a cutter 12 m/s faster than the
ego entered the lane 20-30 m ahead where 10 were asked)."""
CUT_IN_ENTRY_S = 1.2
"""How long (s) after it turns a cut-in's centre enters the lane (`CUT_IN_LOOK_AHEAD_S`): it moves across when its lead
and speed then, as it would close on them once free of its own lane's traffic, are the asked ones (the gap acceptance
on the moment of entry, not on the present: a cutter held 4 m/s slower than an ego speeding up by a car ahead in its
own lane never matched its speed there, and never moved across)."""
CUT_IN_WAIT_DECEL = 2.0
"""The hardest a cut-in brakes in its own lane (m/s^2), letting the other come up before it moves across: comfortable,
as a driver drops back to a gap in the next lane. Where the other brakes, this on top of its braking (at most
`SCRIPT_HARD_BRAKE` in all): a follower braking for the traffic does not leave it far ahead."""
CUT_IN_COMMITTED_M = 1.0
"""How far from its own lane's centre toward the other's (m) a cut-in has moved when it is committed: from there it
goes on across, whatever the gap does meanwhile (never back and forth between the lanes); a real agent off its lane's
centre by half a metre at the start is not (one 0.6 m off turned across at once, 30 m ahead, where 14.5 were asked)."""


OTHER_IN_LANE_M = 0.75
"""The other agent keeps to the lane a cut-in moves into while its centre is within this (m) of the lane's centre
(and its heading within `OTHER_IN_LANE_HEADING`); farther, it drives its own way (`way_of`)."""
OTHER_IN_LANE_HEADING = math.radians(6.0)
WAY_BEHIND_M = 60.0
"""How far back (m) the way a cut-in reads is drawn behind its lane's start, or behind the other on its heading line:
a follower behind where the lane was drawn from still projects onto it, so the lead is read true."""
WAY_AHEAD_M = 150.0
"""How far ahead of the other (m) its heading line goes, where it has left its lane."""


def _heading_off(heading: float, path: np.ndarray, segment: int) -> float:
    """How far `heading` is off `path`'s `segment`-th segment (rad, -pi to pi)."""
    along = path[segment + 1] - path[segment]
    return math.remainder(heading - math.atan2(along[1], along[0]), math.tau)


def way_of(other: list[float], lane: np.ndarray) -> np.ndarray:
    """The way the other agent drives on, as a cut-in reads it from where the other is now [P, 2]: `lane` (drawn
    `WAY_BEHIND_M` back along its first segment) while the other keeps to it, else the other's heading line: a
    planner that leaves its lane (a constant-velocity ego on a bend) is cut in front of where it goes, the path the
    judge reads, not the lane it left."""
    back = lane[0] - lane[1]
    back = lane[0] + WAY_BEHIND_M * back / max(float(np.hypot(*back)), 1e-9)
    way = np.concatenate([back[None], lane])
    found = project_on_polyline(np.array([other[:2]]), way)
    near = float(found.distance[0]) <= OTHER_IN_LANE_M
    if near and abs(_heading_off(other[2], way, int(found.segment[0]))) <= OTHER_IN_LANE_HEADING:
        return way
    forward = np.array([math.cos(other[2]), math.sin(other[2])])
    return np.stack([np.asarray(other[:2]) - WAY_BEHIND_M * forward, np.asarray(other[:2]) + WAY_AHEAD_M * forward])


def _lead_and_offset(state: list[float], other: list[float], path: np.ndarray) -> tuple[float, float, float]:
    """How far the agent's centre is ahead of the other's along `path` (m), how far the agent is off it (m), and how
    far its heading is off the path's there (rad)."""
    found = project_on_polyline(np.array([state[:2], other[:2]]), path)
    heading_off = _heading_off(state[2], path, int(found.segment[0]))
    return float(found.station[0] - found.station[1]), float(found.distance[0]), heading_off


def _keep_lead(
    lead_m: float,
    lead: float,
    state: list[float],
    other: list[float],
    other_accel: float = 0.0,
    hardest: float = -CUT_IN_ACCELERATIONS[0],
) -> float:
    """The acceleration (m/s^2) that brings the agent to `lead_m` ahead of the other (behind it where negative) and to
    its speed (within `CUT_IN_ACCELERATIONS`), on top of the other's own `other_accel`, braking at most `hardest`: it
    closes on the lead no faster than it can shed that speed again at `CUT_IN_APPROACH` (`_closing`)."""
    correction = CUT_IN_SPEED_GAIN * (_closing(lead_m - lead) - (state[3] - other[3]))
    accel = other_accel + float(np.clip(correction, *CUT_IN_ACCELERATIONS))
    return float(np.clip(accel, -hardest, CUT_IN_ACCELERATIONS[1]))


CUT_IN_APPROACH = 1.5
"""The relative deceleration (m/s^2) a scripted agent plans to match the other's speed with as it reaches its lead:
the damped law alone (`CUT_IN_GAP_GAIN`, `CUT_IN_SPEED_GAIN`) closes a large gap faster than the acceleration limits
can undo: an overtake from 15 m behind, 4 m/s faster than the other, ran 22 m past its lead and never moved across
within 8 s (docs/testing.md, 'Cut-ins that arrive at their lead')."""


def _closing(error: float) -> float:
    """How fast (m/s, signed as `error`) the agent closes on its lead `error` m away: the damped law's
    `CUT_IN_GAP_GAIN` / `CUT_IN_SPEED_GAIN` per metre near it, and no faster than stopping at `CUT_IN_APPROACH` allows
    farther off (a braking curve: it arrives at the other's speed, without overshooting)."""
    distance = abs(error)
    return math.copysign(
        min(CUT_IN_GAP_GAIN / CUT_IN_SPEED_GAIN * distance, math.sqrt(2.0 * CUT_IN_APPROACH * distance)), error
    )


EASE_OFF_MPS = 4.0
"""The most a lead easing off for its follower to close in (`Braking.closes_to_m`) drives slower than the follower
(m/s): from 40 m back a follower comes within 20 m in about 5 s, inside an episode."""
EASE_OFF_ACCELERATIONS = (-2.0, 2.0)
"""What a lead easing off accelerates within (m/s^2): gentle, so that its braking before the trigger is not what the
judge reads as the hard braking asked."""
EASE_OFF_MARGIN_M = 1.5
"""How far inside the asked gap a lead easing off aims (m), so that the gap crosses it rather than creeping up to it."""


def ease_off(
    gap_to: float, floor: float, state: list[float], other: list[float], other_accel: float, half_lengths: float
) -> float:
    """The acceleration (m/s^2) of a lead letting the follower `other` close to `gap_to` m bumper to bumper
    (`EASE_OFF_MARGIN_M` inside it; `half_lengths`: the sum of the two): slower than the follower by the braking
    curve of the gap left (`_closing`, at most `EASE_OFF_MPS`) and never below `floor` m/s, on top of the follower's
    own `other_accel`; a follower nearer than the gap sees it pull away again."""
    gap = math.hypot(state[0] - other[0], state[1] - other[1]) - half_lengths
    error = gap_to - EASE_OFF_MARGIN_M - gap  # negative while the follower is farther back than asked
    slower = float(np.clip(_closing(error), -EASE_OFF_MPS, EASE_OFF_MPS))
    correction = CUT_IN_SPEED_GAIN * (max(other[3] + slower, floor) - state[3])
    return float(np.clip(other_accel + correction, *EASE_OFF_ACCELERATIONS))


@dataclass(frozen=True)
class Braking(Script):
    """From `start_s`, slowing at `deceleration` m/s^2 to rest and standing, and keeping to its path throughout
    (pure pursuit), never into the traffic ahead (`keep_behind`); before, the model's acceleration, or, with
    `closes_to_m`, easing off until the other agent behind is within that bumper gap (`ease_off`, no slower than
    `floor_mps`): a braking lead placed for a trigger on its follower's gap."""

    start_s: float
    deceleration: float
    closes_to_m: float | None = None
    floor_mps: float = 0.0

    def plan(self, now: ScriptState) -> np.ndarray:
        out = np.full((now.count, 2), np.nan)
        state = [float(v) for v in now.agent]
        other = None if now.other is None else [float(v) for v in now.other]
        half_lengths = 0.5 * (now.size[0] + now.other_box[0])
        for k in range(now.count):
            t = now.elapsed_s + k * now.per_action * now.dt
            if t >= self.start_s - 1e-6:
                accel = keep_behind(-self.deceleration, state, now.path, now, traffic_at(now, k))
            elif self.closes_to_m is not None and other is not None:
                eased = ease_off(self.closes_to_m, self.floor_mps, state, other, now.other_accel, half_lengths)
                accel = keep_behind(eased, state, now.path, now, traffic_at(now, k))
            else:
                accel = np.nan
            ahead = max(LOOK_AHEAD_MIN_M, LOOK_AHEAD_S * state[3])
            rate = pursuit_rate(*state, now.path, ahead, now.max_yaw_rate)
            out[k] = (accel, rate)
            for _ in range(now.per_action):
                unicycle_step(state, 0.0 if np.isnan(accel) else accel, rate, now.dt)
                if other is not None:
                    unicycle_step(other, now.other_accel, 0.0, now.dt)
        return out


@dataclass(frozen=True)
class CuttingIn(Script):
    """Into the other's way (`way_of`: its lane, the target's `new_lane` or else its path, while it keeps to it;
    pure pursuit) once clear ahead of the other (`CUT_IN_CLEAR_M`), at about its lead and speed
    (`CUT_IN_MATCHED_MPS`; in its own lane until then, `_across`), its speed set to reach and keep `lead_m` (centre to
    centre along the way) ahead of the other wherever the other drives, the other's braking matched until it is in
    the lane; once in the lane and `settle_s` has passed, on at `cruise_mps`: a slower vehicle cutting in (Euro NCAP's
    cut-in), which a follower that ignores it runs into."""

    lead_m: float
    settle_s: float
    cruise_mps: float
    moves_from_s: float = 0.0
    """It moves across no earlier than this (s after its start); until then it keeps its lead in its own lane (a
    timed cut-in placed for its trigger: `CutIn.placed`)."""

    def plan(self, now: ScriptState) -> np.ndarray:
        out = np.full((now.count, 2), np.nan)
        if now.other is None:
            return out
        theirs = now.new_lane if now.new_lane is not None and len(now.new_lane) >= 2 else now.path
        own = now.own_lane if now.own_lane is not None and len(now.own_lane) >= 2 else None
        state, other = [float(v) for v in now.agent], [float(v) for v in now.other]
        into = way_of(other, theirs)
        wait_decel = CUT_IN_WAIT_DECEL + max(-now.other_accel, 0.0)
        moving = bool(now.memory.get("across", False))
        for k in range(now.count):
            t = now.elapsed_s + k * now.per_action * now.dt
            lead, off, turned = _lead_and_offset(state, other, into)
            seen = traffic_at(now, k)
            moving = moving or own is None or off <= CUT_IN_IN_LANE_M
            if not moving and own is not None and t >= self.moves_from_s:
                moving = self._across(lead, off, state, other, own, into, now, seen)
            if moving and k == 0:  # executed: begun, it goes on across (never back and forth between the lanes)
                now.memory["across"] = True
            if t >= self.settle_s and off <= CUT_IN_IN_LANE_M:
                accel = float(np.clip(CUT_IN_SPEED_GAIN * (self.cruise_mps - state[3]), *CUT_IN_ACCELERATIONS))
            else:
                # the other's braking matched until the cut-in is in its lane (a follower braking for the traffic
                # does not leave it behind or far ahead); once in, that braking is the other's answer to the cut-in,
                # and matching it would brake both to a stand
                matched = now.other_accel if off > CUT_IN_IN_LANE_M else 0.0
                accel = _keep_lead(self.lead_m, lead, state, other, matched, SCRIPT_HARD_BRAKE)
            if moving:
                if off > CUT_IN_IN_LANE_M or abs(turned) > CUT_IN_ALIGNED:  # not at a crawl
                    accel = max(accel, CUT_IN_SPEED_GAIN * (CUT_IN_CROSSING_MIN_MPS - state[3]))
                ahead, lane = max(CUT_IN_LOOK_AHEAD_MIN_M, CUT_IN_LOOK_AHEAD_S * state[3]), into
            else:  # its own lane, letting the other come up without braking hard
                accel = max(accel, -wait_decel)
                ahead, lane = max(LOOK_AHEAD_MIN_M, LOOK_AHEAD_S * state[3]), own
            rate = pursuit_rate(*state, lane, ahead, now.max_yaw_rate)
            accel = keep_behind(accel, state, lane, now, with_other(seen, other, now))
            out[k] = (accel, rate)
            for _ in range(now.per_action):
                unicycle_step(state, accel, rate, now.dt)
                unicycle_step(other, now.other_accel, 0.0, now.dt)
        return out

    def _across(
        self,
        lead: float,
        off: float,
        state: list[float],
        other: list[float],
        own: np.ndarray,
        into: np.ndarray,
        now: ScriptState,
        traffic: np.ndarray,
    ) -> bool:
        """Whether the cut-in moves across now: committed (`CUT_IN_COMMITTED_M` nearer the lane it moves into, `off`
        m away, than its own lane's centre is), or clear ahead of the other (`CUT_IN_CLEAR_M`) with its place in the
        lane free of the traffic (`slot_free`), and on entering the lane (`_at_entry`) near its lead
        (`CUT_IN_GAP_SLACK_M`, `CUT_IN_FAR_SLACK_M`) and within `CUT_IN_MATCHED_MPS` of the other's speed."""
        centre = point_at(own, float(project_on_polyline(np.array([state[:2]]), own).station[0]))
        if float(project_on_polyline(centre[None, :2], into).distance[0]) - off > CUT_IN_COMMITTED_M:
            return True
        if lead < CUT_IN_CLEAR_M or not slot_free(state, into, now, traffic):
            return False
        entry, faster = self._at_entry(lead, state[3], other[3], now.other_accel, now.dt)
        near = max(CUT_IN_CLEAR_M, self.lead_m - CUT_IN_GAP_SLACK_M) <= entry <= self.lead_m + CUT_IN_FAR_SLACK_M
        return near and abs(faster) <= CUT_IN_MATCHED_MPS

    def _at_entry(self, lead: float, speed: float, theirs: float, other_accel: float, dt: float) -> tuple[float, float]:
        """The lead (m) and how much faster than the other (m/s) the cut-in is `CUT_IN_ENTRY_S` after it turns now:
        closing on its lead as it does while it moves across (`_keep_lead`, the other's braking matched, at least
        `CUT_IN_CROSSING_MIN_MPS`), the other at its present acceleration. The traffic of the lane it moves into is
        `slot_free`'s: reading its 1-s headway here too (`keep_behind`) refused held-out cut-ins into a gap behind a
        faster car that the judge then saw happen."""
        for _ in range(round(CUT_IN_ENTRY_S / dt)):
            state, their = [0.0, 0.0, 0.0, speed], [0.0, 0.0, 0.0, theirs]
            accel = _keep_lead(self.lead_m, lead, state, their, other_accel, SCRIPT_HARD_BRAKE)
            accel = max(accel, CUT_IN_SPEED_GAIN * (CUT_IN_CROSSING_MIN_MPS - speed))
            speed, theirs = max(speed + accel * dt, 0.0), max(theirs + other_accel * dt, 0.0)
            lead += (speed - theirs) * dt
        return lead, speed - theirs


TRAIL_SPACING_M = 1.0
"""A followed agent's trail keeps a point every this (m) of its driven way (`trail`)."""
TRAIL_AHEAD_M = 80.0
"""A followed agent's trail goes on along its heading this far (m): where it drives next, as far as a follower can
tell."""


def trail(now: ScriptState) -> np.ndarray:
    """The way the other agent has driven since the script's first plan, from where the agent was then (a point every
    `TRAIL_SPACING_M`, kept in `now.memory['trail']`), to where the other is now and on along its heading for
    `TRAIL_AHEAD_M` [P, 2]: a follower's path wherever the other turns, read from the simulation as it runs (never
    from the log)."""
    assert now.other is not None
    here = [float(now.other[0]), float(now.other[1])]
    points = now.memory.setdefault("trail", [[float(now.agent[0]), float(now.agent[1])]])
    if math.dist(points[-1], here) >= TRAIL_SPACING_M:
        points.append(here)
    heading = float(now.other[2])
    ahead = [here[0] + TRAIL_AHEAD_M * math.cos(heading), here[1] + TRAIL_AHEAD_M * math.sin(heading)]
    line = points if math.dist(points[-1], here) < 1e-3 else [*points, here]
    return np.asarray([*line, ahead], np.float64)


FOLLOW_STANDING_M = 2.0
"""The bumper gap (m) a follower keeps behind a slow or standing other, where its headway asks for less."""


@dataclass(frozen=True)
class Following(Script):
    """Keeping `headway_s` of time gap behind the other agent at the other's speed as it is (at least
    `FOLLOW_STANDING_M`, bumper to bumper), along the way the other drives (`trail`: behind it wherever it turns, not
    along the lane the target read), by pure pursuit: a tailgater closing in to a short headway and sitting there
    however the other's speed changes."""

    headway_s: float

    def plan(self, now: ScriptState) -> np.ndarray:
        out = np.full((now.count, 2), np.nan)
        if now.other is None:
            return out
        bumpers = 0.5 * (now.size[0] + now.other_box[0])  # centre to centre, bumpers touching
        path = trail(now)
        state, other = [float(v) for v in now.agent], [float(v) for v in now.other]
        for k in range(now.count):
            lead, _, _ = _lead_and_offset(state, other, path)
            behind = -(bumpers + max(self.headway_s * other[3], FOLLOW_STANDING_M))
            # the other's braking is not fed forward: a tailgater reacts to the gap and the speeds, late
            accel = keep_behind(_keep_lead(behind, lead, state, other, 0.0), state, path, now, traffic_at(now, k))
            rate = pursuit_rate(*state, path, max(LOOK_AHEAD_MIN_M, LOOK_AHEAD_S * state[3]), now.max_yaw_rate)
            out[k] = (accel, rate)
            for _ in range(now.per_action):
                unicycle_step(state, accel, rate, now.dt)
                unicycle_step(other, now.other_accel, 0.0, now.dt)
        return out


CROSSING_ACCELERATIONS = (-3.0, 3.0)
"""What a scripted crossing may brake and accelerate (m/s^2)."""
CROSSING_SPEED_GAIN = 1.0
"""Per second: the acceleration per m/s a scripted crossing is below (or above) the speed it needs."""
CROSSING_TOP_MPS = 14.0
"""The fastest a scripted crossing drives to make its moment (m/s, 50 km/h; its least speed where that is higher)."""
CROSSING_MEET = 0.5
"""Where the other's front is when a scripted crossing's centre is on the other's path: this share of the distance
within which the other, keeping its speed, runs into the crossing car's side (synchronised arrival, as CARLA's
ScenarioRunner times its junction adversaries: a planner that does not react hits it, one that sees it coming and
brakes does not; docs/simulation.md, 'Scripted manoeuvres')."""
CROSSING_GO_SLACK_S = 0.1
"""A crossing early for its moment sets off once it would be no more than this early (s) at its least speed."""
CROSSING_BISECTIONS = 8
"""Bisections for the speed that makes a crossing's moment (`_speed_for`; 14 - 8 m/s in 2.3 cm/s steps)."""
CROSSING_HOLD_M = 1.0
"""How far short of its stop line (m) the front of a crossing early for its moment stands."""
CROSSING_HOLD_DECEL = 3.0
"""The braking (m/s^2) within which a crossing can still stand short of its stop line; past that it is committed
(a driver's point of no return at a light)."""
CROSSING_APPROACH_MPS = 4.0
"""The least speed (m/s) a crossing early for its moment rolls up to its hold point at, rather than stopping short."""
CROSSING_HOLD_SLACK_M = 0.5
"""A crossing standing this little (m) past its hold point still holds (still short of the line)."""
CROSSING_AT_HOLD_M = 0.1
"""Within this (m) of its hold point a crossing early for its moment comes to rest."""
CROSSING_BRAKE_FROM = 1.0
"""A crossing early for its moment brakes for its hold point once that takes this much (m/s^2) or more."""
CROSSING_STANDING_REACH_M = 12.0
"""A crossing goes at once when the other stands (under `CROSSING_STANDING_MPS`) this close (m) to the crossing, and
waits while it stands farther (the red-light judge's reach for a standing other is 15 m)."""
CROSSING_REANCHOR_M = 5.0
"""A crossing meets the other where the other's heading line crosses its path, when that is within this (m) of the
crossing the target read; farther (a turning other), at that crossing."""
CROSSING_STANDING_MPS = 0.5
"""Under this speed (m/s) the other counts as standing for a crossing's timing, unless it is setting off."""
CROSSING_SETTING_OFF = 0.3
"""An other under `CROSSING_STANDING_MPS` accelerating at this (m/s^2) or more is setting off, not standing."""
CROSSING_OTHER_ACCEL = 2.0
"""The most acceleration (m/s^2) a crossing's timing expects of the other (its measured one, where it speeds up)."""


def _cover_s(distance: float, speed: float, toward: float, dt: float) -> float:
    """How long (s) covering `distance` m takes from `speed` under the crossing's speed law toward the speed `toward`
    (at most 80 s; `dt`-s steps)."""
    travelled, t = 0.0, 0.0
    while travelled < distance and t < 80.0:
        accel = float(np.clip(CROSSING_SPEED_GAIN * (toward - speed), *CROSSING_ACCELERATIONS))
        speed = max(speed + accel * dt, 0.0)
        travelled += speed * dt
        t += dt
    return t


def _reach_s(distance: float, speed: float, accel: float) -> float:
    """How long (s) covering `distance` m takes from `speed` at a constant `accel` >= 0 (inf when standing still)."""
    if accel < 1e-6:
        return distance / speed if speed > 1e-6 else (0.0 if distance <= 0.0 else math.inf)
    return (math.sqrt(speed**2 + 2.0 * accel * distance) - speed) / accel


def _speed_for(
    distance: float, speed: float, moment: float, least: float, top: float, dt: float, slowest: float
) -> float:
    """The speed (m/s, within `least` and `top`) toward which the crossing's speed law covers `distance` m from
    `speed` in `moment` s (`slowest`: the time it takes toward `least`): `top` where even that is late, `least` where
    even that is early (bisection)."""
    if slowest <= moment:
        return least
    if _cover_s(distance, speed, top, dt) >= moment:
        return top
    low, high = least, top
    for _ in range(CROSSING_BISECTIONS):
        mid = 0.5 * (low + high)
        low, high = (mid, high) if _cover_s(distance, speed, mid, dt) > moment else (low, mid)
    return 0.5 * (low + high)


def _committed(speed: float, to_hold: float) -> bool:
    """Whether a crossing `to_hold` m short of its hold point (negative: past it) can no longer stand there: past it
    by more than `CROSSING_HOLD_SLACK_M`, or too fast to stop within `CROSSING_HOLD_DECEL`."""
    if to_hold < -CROSSING_HOLD_SLACK_M:
        return True
    return to_hold > 0.0 and speed > CROSSING_STANDING_MPS and speed**2 >= 2.0 * CROSSING_HOLD_DECEL * to_hold


def _toward_hold(accel: float, speed: float, to_hold: float, dt: float) -> float:
    """`accel` (m/s^2), braking instead where standing at the hold point `to_hold` m ahead takes
    `CROSSING_BRAKE_FROM` or more, and to rest once there."""
    if to_hold <= CROSSING_AT_HOLD_M:
        return -speed / dt
    brake = speed**2 / (2.0 * to_hold)
    return min(accel, -brake) if brake >= CROSSING_BRAKE_FROM else accel


@dataclass(frozen=True)
class Crossing(Script):
    """Along its path (pure pursuit, whatever lights or signs it passes) to the crossing at `conflict_m` along it, its
    centre there when the other agent, as it drives, is `CROSSING_MEET` of its collision reach short of it
    (synchronised arrival), re-timed at every step from where the other is. Early for that, it approaches slower (at
    `CROSSING_APPROACH_MPS` at least) and stands `CROSSING_HOLD_M` short of the stop line at `line_m` (None: none)
    until it must set off; once it cannot stand short any more, through at `least_mps` at least (a car that jumps the
    light does not creep), up to `CROSSING_TOP_MPS`; never into the other where that is already in its way ahead. A
    car that runs a red light into another's way, whatever that agent does (docs/simulation.md, 'Scripted
    manoeuvres')."""

    conflict_m: float
    least_mps: float
    line_m: float | None = None

    def _meeting(self, station: float, other: list[float], path: np.ndarray) -> tuple[float, float]:
        """Where it meets the other (re-anchored on the other's live state): the station along its path and the
        other's distance to there (m), where the other's heading line crosses its path within
        `CROSSING_REANCHOR_M` of the crossing (a planner driving straight on, not along the way the target read),
        else the crossing."""
        met = ray_meets_polyline(np.array(other[:2]), other[2], path, station, self.conflict_m + CROSSING_REANCHOR_M)
        if met is not None and met[0] >= self.conflict_m - CROSSING_REANCHOR_M:
            return met
        crossing = point_at(path, self.conflict_m)
        return self.conflict_m, math.hypot(crossing[0] - other[0], crossing[1] - other[1])

    def _moment_s(self, state: list[float], other: list[float], distance: float, now: ScriptState) -> float:
        """When (s from now) its centre is due where it meets the other, the other `distance` m (centre) from there:
        when the other's front, at its speed and its acceleration if it speeds up (up to `CROSSING_OTHER_ACCEL`: an
        ego setting off at a green; one that brakes is taken at its speed), is the meeting distance short of it; 0
        where it is already that close, inf while it stands farther than `CROSSING_STANDING_REACH_M`."""
        length, width = now.size
        other_length, other_width = now.other_box
        front = distance - 0.5 * other_length
        speed, accel = other[3], float(np.clip(now.other_accel, 0.0, CROSSING_OTHER_ACCEL))
        if speed < CROSSING_STANDING_MPS and accel < CROSSING_SETTING_OFF:
            return 0.0 if front <= CROSSING_STANDING_REACH_M else math.inf
        there = speed + accel * _reach_s(max(front, 0.0), speed, accel)  # its speed when it gets there
        meet = CROSSING_MEET * (0.5 * width + 0.5 * (length + other_width) * there / max(state[3], self.least_mps))
        return _reach_s(max(front - meet, 0.0), speed, accel)

    def plan(self, now: ScriptState) -> np.ndarray:
        out = np.full((now.count, 2), np.nan)
        state = [float(v) for v in now.agent]
        other = None if now.other is None else [float(v) for v in now.other]
        top = max(CROSSING_TOP_MPS, self.least_mps)
        hold = None if self.line_m is None else self.line_m - CROSSING_HOLD_M - 0.5 * now.size[0]  # its centre's
        for k in range(now.count):
            station = float(project_on_polyline(np.array([state[:2]]), now.path).station[0])
            meet_m, distance = (self.conflict_m, 0.0) if other is None else self._meeting(station, other, now.path)
            left = meet_m - station
            if left <= 0.0 or other is None:
                need = max(state[3], self.least_mps)
                accel = CROSSING_SPEED_GAIN * (need - state[3])
            else:
                moment = self._moment_s(state, other, distance, now)
                slowest = _cover_s(left, state[3], self.least_mps, now.dt)  # through at its least speed
                early = slowest < moment - CROSSING_GO_SLACK_S
                if hold is None or not early or _committed(state[3], hold - station):
                    need = _speed_for(left, state[3], moment, self.least_mps, top, now.dt, slowest)
                    accel = CROSSING_SPEED_GAIN * (need - state[3])
                else:  # early: slower, and standing short of the line rather than creeping through it
                    approach = max(left / moment, CROSSING_APPROACH_MPS)
                    accel = _toward_hold(CROSSING_SPEED_GAIN * (approach - state[3]), state[3], hold - station, now.dt)
            accel = float(np.clip(accel, *CROSSING_ACCELERATIONS))
            accel = keep_behind(accel, state, now.path, now, with_other(traffic_at(now, k), other, now))
            rate = pursuit_rate(*state, now.path, max(LOOK_AHEAD_MIN_M, LOOK_AHEAD_S * state[3]), now.max_yaw_rate)
            out[k] = (accel, rate)
            for _ in range(now.per_action):
                unicycle_step(state, accel, rate, now.dt)
                if other is not None:
                    unicycle_step(other, now.other_accel, 0.0, now.dt)
        return out
