"""The stop lines of a scene's stop signs (docs/testing.md, 'Step info'): on each lane a sign controls, the point of
the lane nearest the sign, with the lane's heading there. WOMD signs name the lanes they govern, mostly the junction
lanes that start at the line (sometimes the approach lanes that end there), so the lane point nearest the sign is the
line either way. An agent passes a line when its centre goes over it along the lane, close to the lane and heading
its way, between two steps."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from langtraj.angles import wrap_angle
from langtraj.polylines import arc_lengths, point_at, project_on_polyline
from langtraj.scenario.model import RoadMap
from langtraj.scenario.types import MapFeatureType

STOP_LINE_HALF_WIDTH_M = 2.5
"""How far beside a stop line's lane point an agent's centre may pass and still pass the line (half a lane, and
some)."""
STOP_LINE_MAX_HEADING = math.radians(45.0)
"""An agent heading more than this off the lane at its stop line crosses the line rather than passes it."""


@dataclass(frozen=True)
class StopLines:
    """One row per (sign, controlled lane): the line's point [K, 2] and the lane's heading there [K]."""

    points: np.ndarray  # float64 [K, 2]
    headings: np.ndarray  # float64 [K]

    @classmethod
    def of(cls, road_map: RoadMap) -> StopLines:
        """The stop lines of every stop sign of `road_map` on the lanes it controls (a lane the map lacks is left
        out)."""
        lanes = {f.id: f for f in road_map if f.type.is_lane and len(f.points) >= 2}
        points, headings = [], []
        for sign in road_map:
            if sign.type != MapFeatureType.STOP_SIGN or not len(sign.points):
                continue
            for lane_id in sign.controlled_lanes:
                lane = lanes.get(int(lane_id))
                if lane is None:
                    continue
                line = lane.points[:, :2].astype(np.float64)
                station = float(project_on_polyline(sign.points[0, :2], line).station)
                station = min(station, float(arc_lengths(line)[-1]))
                ahead = point_at(line, min(station + 0.5, float(arc_lengths(line)[-1])))
                behind = point_at(line, max(station - 0.5, 0.0))
                points.append(point_at(line, station))
                headings.append(math.atan2(ahead[1] - behind[1], ahead[0] - behind[0]))
        return cls(np.array(points, np.float64).reshape(-1, 2), np.array(headings, np.float64))

    def __len__(self) -> int:
        return len(self.headings)

    def passed(self, before: np.ndarray, now: np.ndarray, heading: np.ndarray) -> np.ndarray:
        """bool [A]: which of the agents at `before` [A, 2] and then `now` [A, 2], heading `heading` [A] now, passed
        a stop line between the two."""
        if not len(self):
            return np.zeros(len(now), bool)
        cos, sin = np.cos(self.headings), np.sin(self.headings)

        def along(xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # [A, K] each: along the lane and beside it
            rel = xy[:, None, :] - self.points[None]
            return rel[..., 0] * cos + rel[..., 1] * sin, -rel[..., 0] * sin + rel[..., 1] * cos

        was, _ = along(np.asarray(before, np.float64))
        is_, beside = along(np.asarray(now, np.float64))
        aligned = np.abs(wrap_angle(np.asarray(heading, np.float64)[:, None] - self.headings[None])) <= (
            STOP_LINE_MAX_HEADING
        )
        return ((was < 0.0) & (is_ >= 0.0) & (np.abs(beside) <= STOP_LINE_HALF_WIDTH_M) & aligned).any(axis=1)
