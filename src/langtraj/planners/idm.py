"""The IDM lane follower: the Intelligent Driver Model along the observation's route, pure-pursuit steering
(docs/testing.md, 'Built-in planners').

A reference planner for the suites: it follows its route, keeps its distance to whatever occupies the route ahead
(vehicles, cyclists, pedestrians alike), stops for red lights and slows for curves; it reads nothing but the
observation, so it runs in or out of process. Pure numpy, well under a millisecond per step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from langtraj.angles import wrap_angle
from langtraj.car_following import idm_interaction
from langtraj.env.spaces import MAX_ACCEL, MAX_YAW_RATE, AgentColumn, EgoColumn
from langtraj.planners.base import PLANNERS, Planner
from langtraj.polylines import arc_lengths, point_at, project_on_polyline
from langtraj.scenario.model import STEP_SECONDS
from langtraj.scenario.types import TrafficLightState

STOP_STATES = tuple(int(state) for state in TrafficLightState if state.is_stop)
"""Light states that mean stop (`TrafficLightState.is_stop`: arrow stop, stop, flashing stop)."""
CAUTION_STATES = tuple(int(state) for state in TrafficLightState if state.is_caution)
"""Light states that mean caution (`TrafficLightState.is_caution`: arrow, plain and flashing): stop only where a
comfortable stop is still possible."""
_BEHIND_M = 50.0  # the route is extended this far behind its first point, so agents alongside get signed stations
CROSSING_MAX_ANGLE = math.radians(120.0)
"""Agents heading more than this off the route count as oncoming, not crossing (`IDMConfig.crossing_traffic`)."""
CUT_IN_SAMPLES = 5
"""Times along `IDMConfig.cut_in_horizon` at which the agents' forecasts are checked against the corridor."""


@dataclass(frozen=True)
class IDMConfig:
    """Parameters of `IDMPlanner`: the IDM's (Treiber et al. 2000), the obstacle corridor, curve speeds and the
    pure-pursuit look-ahead."""

    desired_speed: float = 13.9
    """Speed on a free straight road where the map gives no speed limit, m/s (50 km/h, urban). Where it does,
    the route's limit (`route_speed_limit`) times `speed_limit_factor` instead; lower limits and curves ahead lower
    it in time to reach them (`comfortable_decel`, `max_lateral_accel`)."""
    speed_limit_factor: float = 1.0
    """The share of the speed limit the planner drives at."""
    time_headway: float = 1.5
    """Desired time gap to the leader, s."""
    min_gap: float = 2.0
    """Bumper-to-bumper gap kept when stopped behind a leader or before a stop line, m."""
    max_accel: float = 1.5
    """Largest acceleration, m/s^2."""
    comfortable_decel: float = 2.0
    """Comfortable deceleration, m/s^2: the IDM's b, the most a free road (a lower desired speed) brakes with, the
    test for stopping at a caution light and the gentle stop where there is no route."""
    exponent: float = 4.0
    """The IDM's acceleration exponent (delta)."""
    hard_brake: float = MAX_ACCEL
    """Hardest braking, m/s^2 (the action bound): the IDM's deceleration is floored at -hard_brake."""
    corridor_margin: float = 0.3
    """An agent is on the route when its box comes within (ego width + its lateral extent) / 2 + this of it, m."""
    cut_in_horizon: float = 1.0
    """An agent heading the ego's way also counts as on the route when its constant-velocity forecast puts it there
    within this many seconds (a cut-in seen coming), s; 0: only where it is now."""
    crossing_traffic: bool = False
    """Whether agents crossing the ego's way count too when that forecast puts them on the route ahead (a car
    running a red light seen coming; not oncoming ones, more than `CROSSING_MAX_ANGLE` off the ego's way); the IDM's
    own: only agents heading its way."""
    light_lateral: float = 1.5
    """A light's stop point is on the route when at most this far from it laterally, m."""
    max_lateral_accel: float = 2.0
    """Curves ahead cap the speed at sqrt(this / curvature), reached by braking at `comfortable_decel`."""
    lookahead_min: float = 4.0
    lookahead_time: float = 1.0
    """Pure pursuit looks max(lookahead_min, lookahead_time x speed) metres ahead along the route."""
    curvature_window: int = 2
    """Route segments the curvature is measured over (heading change between segments this far apart)."""


@PLANNERS.register
class IDMPlanner(Planner):
    """Follows the route at the IDM's speed behind the nearest obstacle on it (an agent or a stop line), steering
    by pure pursuit; where the route is invalid, holds its heading and brakes gently to a stop."""

    name = "idm"
    action_kind = "control"

    def __init__(self, config: IDMConfig | None = None):
        self.config = config or IDMConfig()

    def act(self, observation: dict[str, np.ndarray]) -> np.ndarray:
        ego = np.asarray(observation["ego"], np.float64)
        speed = max(0.0, float(ego[EgoColumn.SPEED])) if np.isfinite(ego[EgoColumn.SPEED]) else 0.0
        length, width = float(ego[EgoColumn.LENGTH]), float(ego[EgoColumn.WIDTH])
        on_route = np.asarray(observation["route_valid"], bool)
        route = np.asarray(observation["route"], np.float64)[on_route]
        limits = np.asarray(observation["route_speed_limit"], np.float64)[on_route]
        finite = np.isfinite(route).all(axis=1)
        route, limits = route[finite], limits[finite]
        if len(route) > 1:  # repeated points have no heading
            moved = np.concatenate([[True], np.linalg.norm(np.diff(route, axis=0), axis=1) > 1e-6])
            route, limits = route[moved], limits[moved]
        if len(route) == 0:
            desired = 0.0
            corridor = np.array([[0.0, 0.0], [100.0, 0.0]])  # obstacles straight ahead still count
            yaw_rate = 0.0
        else:
            desired = min(self._limit_speed(route, limits), self._curve_speed(route))
            corridor = route
            yaw_rate = self._pursuit(route, speed)
        accel = self._free_accel(speed, desired)
        obstacles = self._obstacles(observation, corridor, speed, length, width)
        if len(obstacles):
            accel += float(self._interaction(speed, obstacles[:, 0], obstacles[:, 1]).min())
        accel = np.clip(accel, max(-self.config.hard_brake, -speed / STEP_SECONDS), self.config.max_accel)
        return np.clip([accel, yaw_rate], [-MAX_ACCEL, -MAX_YAW_RATE], [MAX_ACCEL, MAX_YAW_RATE]).astype(np.float32)

    def _free_accel(self, speed: float, desired: float) -> float:
        """The IDM's free-road term a (1 - (v / v0)^delta), floored at the comfortable deceleration."""
        c = self.config
        if desired <= 0.0:
            return -c.comfortable_decel if speed > 0.0 else 0.0
        return max(-c.comfortable_decel, c.max_accel * (1.0 - (speed / desired) ** c.exponent))

    def _interaction(self, speed: float, gaps: np.ndarray, lead_speeds: np.ndarray) -> np.ndarray:
        """The IDM's interaction term per obstacle (`car_following.idm_interaction`) with this planner's parameters."""
        c = self.config
        return idm_interaction(
            speed,
            gaps,
            lead_speeds,
            max_accel=c.max_accel,
            comfortable_decel=c.comfortable_decel,
            time_headway=c.time_headway,
            min_gap=c.min_gap,
        )

    def _limit_speed(self, route: np.ndarray, limits: np.ndarray) -> float:
        """The desired speed the speed limits give: the limit where the ego is (`desired_speed` where none is
        known), lowered where a lower limit ahead can still just be reached by braking at the comfortable
        deceleration."""
        c = self.config
        known = np.isfinite(limits) & (limits > 0)
        here = c.desired_speed if not known[0] else c.speed_limit_factor * float(limits[0])
        if not known.any():
            return here
        stations = arc_lengths(route)[known]
        reachable = np.sqrt((c.speed_limit_factor * limits[known]) ** 2 + 2.0 * c.comfortable_decel * stations)
        return float(min(here, reachable.min()))

    def _curve_speed(self, route: np.ndarray) -> float:
        """The speed curves allow now: infinite on a straight road, lowered where a curve ahead asks for less than
        can still be reached by braking at the comfortable deceleration."""
        c = self.config
        k = c.curvature_window
        if len(route) < k + 2:
            return math.inf
        segments = np.diff(route, axis=0)
        headings = np.arctan2(segments[:, 1], segments[:, 0])
        middles = arc_lengths(route)[:-1] + 0.5 * np.linalg.norm(segments, axis=1)  # stations of segment middles
        turn = np.abs(wrap_angle(headings[k:] - headings[:-k]))
        curvature = turn / np.maximum(middles[k:] - middles[:-k], 1e-6)
        station = middles[:-k]  # where the turn starts
        with np.errstate(divide="ignore"):
            limit = np.sqrt(c.max_lateral_accel / curvature + 2.0 * c.comfortable_decel * station)
        return float(limit.min())

    def _pursuit(self, route: np.ndarray, speed: float) -> float:
        """Pure pursuit: yaw rate = speed x 2 y / L^2 toward the route point `lookahead` metres along it
        (extended straight past its end), clipped to the action bound."""
        c = self.config
        lookahead = max(c.lookahead_min, c.lookahead_time * speed)
        if len(route) == 1:
            target = route[0]
        else:
            arc = arc_lengths(route)
            if lookahead <= arc[-1]:
                target = point_at(route, lookahead)
            else:
                direction = route[-1] - route[-2]
                norm = float(np.linalg.norm(direction))
                target = route[-1] + (lookahead - arc[-1]) * direction / max(norm, 1e-9)
        distance2 = float(target @ target)
        if distance2 < 0.25:
            return 0.0
        return float(np.clip(speed * 2.0 * target[1] / distance2, -MAX_YAW_RATE, MAX_YAW_RATE))

    def _obstacles(
        self, observation: dict[str, np.ndarray], route: np.ndarray, speed: float, length: float, width: float
    ) -> np.ndarray:
        """(gap, speed along the route) [K, 2] of the agents whose boxes overlap the route's corridor ahead and
        of the stop lines ahead whose lights say stop; gaps are bumper to bumper (a stop line has no length)."""
        c = self.config
        back = route[1] - route[0] if len(route) > 1 else np.array([1.0, 0.0])
        back = route[0] - _BEHIND_M * back / max(float(np.linalg.norm(back)), 1e-9)
        line = np.concatenate([back[None], route])
        headings = np.arctan2(np.diff(line[:, 1]), np.diff(line[:, 0]))
        found = []

        agents = np.asarray(observation["agents"], np.float64)
        valid = np.asarray(observation["agents_valid"], bool) & np.isfinite(agents).all(axis=1)
        if valid.any():
            agents = agents[valid]
            on = project_on_polyline(agents[:, [AgentColumn.X, AgentColumn.Y]], line)
            station = on.station - _BEHIND_M
            along = headings[on.segment]
            relative = agents[:, AgentColumn.HEADING] - along
            cos, sin = np.abs(np.cos(relative)), np.abs(np.sin(relative))
            agent_length, agent_width = agents[:, AgentColumn.LENGTH], agents[:, AgentColumn.WIDTH]
            half_lateral = 0.5 * (agent_length * sin + agent_width * cos)
            half_along = 0.5 * (agent_length * cos + agent_width * sin)
            reach = 0.5 * width + half_lateral + c.corridor_margin
            overlaps = np.abs(on.offset) <= reach
            if c.cut_in_horizon > 0:  # same-direction agents whose forecast enters the corridor, in one projection
                times = np.linspace(0.0, c.cut_in_horizon, CUT_IN_SAMPLES + 1)[1:]
                xy, velocity = agents[:, [AgentColumn.X, AgentColumn.Y]], agents[:, [AgentColumn.VX, AgentColumn.VY]]
                ahead_xy = xy[None] + times[:, None, None] * velocity[None]  # [S, K, 2]
                there = project_on_polyline(ahead_xy.reshape(-1, 2), line).offset.reshape(len(times), -1)
                coming = np.cos(relative) > (math.cos(CROSSING_MAX_ANGLE) if c.crossing_traffic else 0.0)
                overlaps |= coming & (np.abs(there) <= reach).any(axis=0)
            ahead = overlaps & (station > 0.0)
            gaps = station - 0.5 * length - half_along
            lead_speeds = agents[:, AgentColumn.VX] * np.cos(along) + agents[:, AgentColumn.VY] * np.sin(along)
            found.append(np.stack([gaps[ahead], lead_speeds[ahead]], axis=1))

        lights = np.asarray(observation["lights"], np.float64)
        states = np.asarray(observation["lights_state"]).astype(np.int64)
        valid = np.asarray(observation["lights_valid"], bool) & np.isfinite(lights).all(axis=1)
        valid &= np.isin(states, STOP_STATES + CAUTION_STATES)
        if valid.any():
            on = project_on_polyline(lights[valid], line)
            gaps = on.station - _BEHIND_M - 0.5 * length
            near = (np.abs(on.offset) <= c.light_lateral) & (gaps > 0.0)
            caution = np.isin(states[valid], CAUTION_STATES)
            can_stop = speed**2 <= 2.0 * c.comfortable_decel * gaps
            stop = near & (~caution | can_stop)
            found.append(np.stack([gaps[stop], np.zeros(int(stop.sum()))], axis=1))
        return np.concatenate(found) if found else np.zeros((0, 2))
