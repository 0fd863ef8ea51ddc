"""Stop lines (docs/testing.md, 'Step info'): where traffic on a lane stops for a stop sign or a signal, as a point
and the lane's heading there. A stop sign's line, on each lane it controls, is the lane point nearest the sign (WOMD
signs name the lanes they govern, mostly the junction lanes that start at the line, sometimes the approach lanes that
end there, so that point is the line either way); a signal's is its stop point, on its lane. An agent passes a line
when its centre goes over it along the lane, within `STOP_LINE_HALF_WIDTH_M` of it and heading the lane's way, between
two steps: matched by heading, not by the WOSAC metric's nearest lane segment, which at a junction's mouth can pick a
crossing lane and miss the pass (`metrics.traffic_lights` keeps the challenge's rule for scoring)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from langtraj.angles import wrap_angle
from langtraj.polylines import arc_lengths, point_at, project_on_polyline
from langtraj.scenario.model import RoadMap, TrafficLights
from langtraj.scenario.types import MapFeatureType

STOP_LINE_HALF_WIDTH_M = 2.5
"""How far beside a stop line's point an agent's centre may pass and still pass the line: half a lane and some, short
of the 3.3-3.7 m to the next lane's line."""
STOP_LINE_MAX_HEADING = math.radians(45.0)
"""An agent heading more than this off the lane at its stop line crosses the line rather than passes it."""


@dataclass(frozen=True)
class StopLines:
    """Stop lines, one a row: the point [K, 2] and the lane's heading there [K]."""

    points: np.ndarray  # float64 [K, 2]
    headings: np.ndarray  # float64 [K]

    @classmethod
    def of_signs(cls, road_map: RoadMap) -> StopLines:
        """One line per (stop sign of `road_map`, lane it controls); a lane the map lacks is left out."""
        lanes = _lanes(road_map)
        found = []
        for sign in road_map:
            if sign.type == MapFeatureType.STOP_SIGN and len(sign.points):
                found += [_on_lane(lanes[i], sign.points[0, :2]) for i in sign.controlled_lanes if i in lanes]
        return cls._of(found)

    @classmethod
    def of_signals(cls, road_map: RoadMap, lights: TrafficLights) -> StopLines:
        """One line per signal of `lights` (row for row, so its states index the lines), at its stop point with its
        lane's heading there; a signal whose lane the map lacks heads nowhere (NaN) and is never passed."""
        lanes = _lanes(road_map)
        found = [
            _on_lane(lanes[int(i)], point[:2]) if int(i) in lanes else (point[:2], math.nan)
            for i, point in zip(lights.lane_ids, lights.stop_points, strict=True)
        ]
        return cls._of(found)

    @classmethod
    def _of(cls, found: list[tuple[np.ndarray, float]]) -> StopLines:
        points = np.array([p for p, _ in found], np.float64).reshape(-1, 2)
        return cls(points, np.array([h for _, h in found], np.float64))

    def __len__(self) -> int:
        return len(self.headings)

    def passed_each(self, before: np.ndarray, now: np.ndarray, heading: np.ndarray) -> np.ndarray:
        """bool [A, K]: which of the agents at `before` [A, 2] and then `now` [A, 2], heading `heading` [A] now,
        passed which line between the two."""
        cos, sin = np.cos(self.headings), np.sin(self.headings)

        def along(xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # [A, K] each: along the lane and beside it
            rel = np.asarray(xy, np.float64)[:, None, :] - self.points[None]
            return rel[..., 0] * cos + rel[..., 1] * sin, -rel[..., 0] * sin + rel[..., 1] * cos

        was, _ = along(before)
        is_, beside = along(now)
        off = np.abs(wrap_angle(np.asarray(heading, np.float64)[:, None] - self.headings[None]))
        return (was < 0.0) & (is_ >= 0.0) & (np.abs(beside) <= STOP_LINE_HALF_WIDTH_M) & (off <= STOP_LINE_MAX_HEADING)

    def passed(self, before: np.ndarray, now: np.ndarray, heading: np.ndarray) -> np.ndarray:
        """bool [A]: which agents passed any of the lines (`passed_each`)."""
        if not len(self):
            return np.zeros(len(now), bool)
        return self.passed_each(before, now, heading).any(axis=1)


def _lanes(road_map: RoadMap) -> dict[int, np.ndarray]:
    return {f.id: f.points[:, :2].astype(np.float64) for f in road_map if f.type.is_lane and len(f.points) >= 2}


def _on_lane(line: np.ndarray, near: np.ndarray) -> tuple[np.ndarray, float]:
    """The point of a lane's centreline [N, 2] nearest `near` [2], and the lane's heading there."""
    end = float(arc_lengths(line)[-1])
    station = min(float(project_on_polyline(np.asarray(near, np.float64), line).station), end)
    ahead, behind = point_at(line, min(station + 0.5, end)), point_at(line, max(station - 0.5, 0.0))
    return point_at(line, station), math.atan2(ahead[1] - behind[1], ahead[0] - behind[0])
