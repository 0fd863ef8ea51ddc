"""The ego against the rules of the road at one step, after nuPlan's closed-loop metrics (docs/testing.md, 'What an
episode measures'): whether it ran a red light (passed the stop line of a signal that shows stop, going its lane's
way: `EpisodeLights.runs`, the one rule for the ego and for right of way), whether it drives against its lane, and how
far it is over the speed limit of its route. The lights are those of the step: replayed from the log, or held at
the start (`LIGHT_MODES`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from langtraj.angles import wrap_angle
from langtraj.errors import InputError
from langtraj.roads import MapIndex
from langtraj.roads.mission import Route
from langtraj.roads.position import LANE_MATCH_RADIUS
from langtraj.roads.stop_lines import StopLines
from langtraj.scenario.model import Scenario
from langtraj.scenario.types import RED_STATES, StateField

LIGHT_MODES = ("log", "held")
"""`log`: each step's lights as the log has them (up to that step), as Waymax and nuPlan replay them; `held`: the
lights at the start, frozen."""
WRONG_WAY_ANGLE = math.radians(150.0)
"""Driving at more than this to the lane it is on, with no lane within reach running its way, is driving against it."""
WRONG_WAY_MIN_SPEED = 1.0
"""Below this (m/s) the ego is turning or standing, not driving against its lane."""


def light_mode(mode: str) -> str:
    """`mode` when it is one of `LIGHT_MODES`, else a one-line InputError naming `lights`."""
    if mode not in LIGHT_MODES:
        raise InputError(f"must be one of {', '.join(LIGHT_MODES)}, got {mode!r}", where="lights")
    return mode


class EpisodeLights:
    """The traffic lights an episode sees at each step, in one of `LIGHT_MODES`: the log's up to that step
    (`TrafficLights.held_at`, never past it) or those at the start; each step's read once for the observation and the
    rules alike. `log` is None for a scene without signals; `lines`, the signals' stop lines (`StopLines.of_signals`),
    row for row with them. `runs` is the one red-light rule, for the ego's `red_light` and for right of way
    (`env.right_of_way`)."""

    def __init__(self, scenario: Scenario, mode: str = "log"):
        lights = scenario.traffic_lights
        self.log = lights if lights is not None and len(lights.lane_ids) else None
        self.lines = None if self.log is None else StopLines.of_signals(scenario.road_map, self.log)
        self.mode, self.start = light_mode(mode), scenario.current_index
        self._read: tuple[int, tuple[np.ndarray, np.ndarray]] | None = None

    def at(self, step: int) -> tuple[np.ndarray, np.ndarray]:
        """Each signal's state int8 [L] and whether it was ever seen, bool [L], as the episode sees them at `step`."""
        assert self.log is not None
        step = step if self.mode == "log" else self.start
        if self._read is None or self._read[0] != step:
            self._read = (step, self.log.held_at(step))
        return self._read[1]

    def runs(
        self, before: np.ndarray, now: np.ndarray, heading: np.ndarray, step: int, logged: bool = False
    ) -> np.ndarray:
        """bool [A]: which agents, at `before` [A, 2] and then at `now` [A, 2] heading `heading` [A], passed the line
        of a signal that shows stop at `step` (as the episode sees it; `logged`: as the log has it, for a step of the
        history) and the line of no signal that does not (a red left arrow beside a green straight at one stop point
        is no run). False for all without signals."""
        if self.log is None or self.lines is None:
            return np.zeros(len(now), bool)
        states, seen = self.log.held_at(step) if logged else self.at(step)
        stop = seen & np.isin(states, [int(s) for s in RED_STATES])
        if not stop.any():
            return np.zeros(len(now), bool)
        each = self.lines.passed_each(before, now, heading)
        return each.any(axis=1) & ~(each & ~stop[None]).any(axis=1)


@dataclass(frozen=True)
class RuleEvents:
    """The ego at one step: `red_light` it crossed a red light's stop point since the last step; `wrong_way` it
    drives against its lane; `over_limit` its speed above the route's speed limit here (m/s; None: no limit known,
    0 at or under it)."""

    red_light: bool
    wrong_way: bool
    over_limit: float | None


class RuleJudge:
    """Judges the ego (scenario row `ego`) of `scenario` on its map (`index`) and `route`, with the lights the
    episode sees (`lights`: replayed from the log or held at the start)."""

    def __init__(self, scenario: Scenario, ego: int, index: MapIndex, route: Route, lights: EpisodeLights):
        self.ego, self.index, self.route, self.lights = ego, index, route, lights

    def judge(self, before: np.ndarray, now: np.ndarray, step: int, station: float) -> RuleEvents:
        """The ego's state before [9] and now [9] (at `step` of the scenario), at `station` along its route."""
        xy = [StateField.X, StateField.Y]
        red = bool(self.lights.runs(before[None, xy], now[None, xy], now[None, StateField.HEADING], step)[0])
        speed = float(np.hypot(now[StateField.VX], now[StateField.VY]))
        _, on_route, limits = self.route.ahead(station, 1, 1.0)
        limit = float(limits[0]) if on_route[0] else math.nan
        over = None if not math.isfinite(limit) else max(speed - limit, 0.0)
        return RuleEvents(red, self._wrong_way(now, speed), over)

    def _wrong_way(self, state: np.ndarray, speed: float) -> bool:
        if speed < WRONG_WAY_MIN_SPEED or not self.index.has_lanes:
            return False
        xy = state[[StateField.X, StateField.Y]].astype(np.float64)
        heading = np.array([state[StateField.HEADING]], np.float64)
        nearest = self.index.match_lanes(xy, radius=LANE_MATCH_RADIUS, exclude_junctions=True)
        if nearest.lane[0] < 0 or abs(float(wrap_angle(heading[0] - nearest.heading[0]))) < WRONG_WAY_ANGLE:
            return False
        ours = self.index.match_lanes(xy, heading, radius=LANE_MATCH_RADIUS, max_heading_diff=math.pi / 2)
        return bool(ours.lane[0] < 0)
