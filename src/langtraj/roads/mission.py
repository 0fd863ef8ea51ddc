"""The ego's route: the lanes it is to drive, from the map (docs/testing.md, 'The route'): the one route a planner
is given (`env`), and the way targets staged toward the ego read for it (`interdrive.targets`, `suggest`).

Where the log holds the ego's future, the route is the chain of lanes from the ego's lane that passes nearest to
where the logged ego went (its mission, as nuPlan and Waymax give a planner its route); otherwise the ego's lane
continued by the straightest exits; off the lane graph, the line along its heading. Only the route is taken from
the log, never the ego's motion along it. Each point carries the speed limit of the lane it lies on (NaN where
the map gives none).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from langtraj.polylines import arc_lengths, project_on_polyline
from langtraj.roads import MapIndex
from langtraj.roads.position import AgentOnLane
from langtraj.roads.routes import chain_path, continued, route, straight_line
from langtraj.scenario.model import FUTURE_STEPS, Scenario
from langtraj.scenario.types import StateField

ROUTE_LENGTH_M = 250.0
"""How far the route reaches beyond the logged end point (or from the ego, without a log)."""
MAX_CHAINS = 256
"""Lane chains compared with the logged path at most (a breadth-first search over exits)."""


@dataclass(frozen=True)
class Route:
    """A route polyline (world frame, a point every `ROUTE_SPACING` m), its arc lengths and each point's speed
    limit."""

    points: np.ndarray  # float64 [P, 2]
    stations: np.ndarray  # float64 [P]
    source: str  # "log" (lanes nearest the logged path), "lanes" (straightest exits) or "heading" (no lane)
    speed_limits: np.ndarray  # float64 [P], m/s; NaN where the map gives none

    @classmethod
    def of(cls, points: np.ndarray, source: str, limits: np.ndarray | None = None, ends: np.ndarray | None = None):
        """The route through `points` (a point every `ROUTE_SPACING` m, as `roads.routes` draws them);
        `limits` [L] the speed limits (m/s) of its successive lanes, the l-th up to arc length `ends[l]` (None: no
        lanes, no limits)."""
        points = np.asarray(points, np.float64)
        stations = arc_lengths(points)
        if limits is None or ends is None:
            speed_limits = np.full(len(points), np.nan)
        else:
            which = np.searchsorted(np.asarray(ends, np.float64), stations, side="right")
            speed_limits = np.asarray(limits, np.float64)[np.minimum(which, len(limits) - 1)]
        return cls(points, stations, source, speed_limits)

    @property
    def length(self) -> float:
        return float(self.stations[-1]) if len(self.stations) else 0.0

    def station(self, xy: np.ndarray) -> float:
        """Arc length of the point of the route nearest `xy`."""
        return float(project_on_polyline(np.asarray(xy, np.float64)[None], self.points).station[0])

    def ahead(self, station: float, count: int, spacing: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """`count` points every `spacing` m from `station` (world frame), which of them lie on the route, and the
        speed limit at each (m/s, NaN: none known or off the route)."""
        wanted = station + spacing * np.arange(count)
        valid = wanted <= self.length + 1e-9
        x = np.interp(wanted, self.stations, self.points[:, 0])
        y = np.interp(wanted, self.stations, self.points[:, 1])
        at = np.clip(np.searchsorted(self.stations, wanted, side="right") - 1, 0, len(self.stations) - 1)
        limits = np.where(valid, self.speed_limits[at], np.nan)
        return np.stack([x, y], -1), valid, limits


def ego_route(index: MapIndex, start: AgentOnLane, xy: np.ndarray, heading: float, logged: np.ndarray) -> Route:
    """The route of an ego at `xy` with `heading` on `start`; `logged` [T, 2] its logged future positions (may be
    empty), which choose among the lane chains ahead."""
    if start.lane < 0:
        return Route.of(straight_line(xy, heading, ROUTE_LENGTH_M), "heading")
    if len(logged) < 2 or float(np.linalg.norm(logged[-1] - xy)) < 2.0:
        return _along(index, [start.lane], start.station, ROUTE_LENGTH_M, "lanes")
    reach = float(arc_lengths(np.concatenate([xy[None], logged]))[-1]) + 20.0
    best, best_error = None, math.inf
    for chain in _chains(index, start.lane, start.station, reach):
        path = chain_path(index, chain, start.station)
        if len(path) < 2:
            continue
        error = float(np.mean(project_on_polyline(logged, path).distance))
        if error < best_error:
            best, best_error = chain, error
    if best is None:
        return _along(index, [start.lane], start.station, ROUTE_LENGTH_M, "lanes")
    return _along(index, best, start.station, reach + ROUTE_LENGTH_M, source="log")


def mission_of(scenario: Scenario, row: int, index: MapIndex) -> Route:
    """The route of the agent at scenario `row` from its pose at the current step (`ego_route`), chosen by its logged
    positions over the simulated future where the log has them: the one route an ego is given (`env`) and targets
    toward it read (`interdrive.suggest`), so both agree."""
    c = scenario.current_index
    state = scenario.agents.states[row, c].astype(np.float64)
    steps = np.arange(c + 1, min(c + 1 + FUTURE_STEPS, scenario.num_steps))
    logged = scenario.agents.states[row, steps[scenario.agents.valid[row, steps]]][:, [StateField.X, StateField.Y]]
    logged = np.asarray(logged, np.float64)
    start = AgentOnLane.of(scenario, row, index)
    xy = state[[StateField.X, StateField.Y]]
    return ego_route(index, start, xy, float(state[StateField.HEADING]), logged[np.isfinite(logged[:, 0])])


def _along(index: MapIndex, lanes: list[int], station: float, length: float, source: str) -> Route:
    """The route along `lanes` from `station` on the first, continued as `route` continues it, with each lane's
    speed limit."""
    chain = continued(index, lanes, station, length)
    spans = np.array([float(index.lane_lengths[lane]) for lane in chain])
    spans[0] -= station
    limits = np.array([index.lane_features[lane].speed_limit_mps for lane in chain], np.float64)
    limits[~(limits > 0)] = np.nan  # unknown (NaN) or nonsense (0 or below)
    return Route.of(route(index, chain, station, length), source, limits, np.cumsum(spans))


def _chains(index: MapIndex, lane: int, station: float, reach: float) -> list[list[int]]:
    """Lane chains from `lane` (at `station`) through exits until each covers `reach` m or ends."""
    done, frontier = [], [([lane], float(index.lane_lengths[lane]) - station)]
    while frontier and len(done) + len(frontier) < MAX_CHAINS:
        chain, length = frontier.pop(0)
        exits = [e for e in index.exits[chain[-1]] if e not in chain] if index.has_connectivity else []
        if length >= reach or not exits:
            done.append(chain)
            continue
        frontier.extend((chain + [e], length + float(index.lane_lengths[e])) for e in exits)
    return done + [chain for chain, _ in frontier]
