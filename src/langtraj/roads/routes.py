"""Paths drawn along the lane graph for targets: a lane's centreline from a station, a route along given lanes
continued by the straightest exits, and the line along an agent's heading off lanes (world frame, points every
`ROUTE_SPACING` m; docs/interdrive.md, 'Targets and feasibility')."""

from __future__ import annotations

import math

import numpy as np

from langtraj.angles import wrap_angle
from langtraj.polylines import arc_lengths, point_at, resample
from langtraj.roads import MapIndex

ROUTE_SPACING = 1.0
"""Spacing of a target's path points (m)."""


def lane_piece(index: MapIndex, lane: int, start: float = 0.0) -> np.ndarray:
    """Lane `lane`'s centreline from `start` (m) to its end."""
    points = np.asarray(index.lane_features[lane].points[:, :2], np.float64)
    keep = arc_lengths(points) > start
    head = point_at(points, start)[None]
    return np.concatenate([head, points[keep]]) if keep.any() else head


def join(pieces: list[np.ndarray]) -> np.ndarray:
    """Pieces of centreline joined and resampled at `ROUTE_SPACING`."""
    out = [p for p in pieces if len(p)]
    return resample(np.concatenate(out), ROUTE_SPACING) if out else np.zeros((0, 2))


def straightest_exit(index: MapIndex, lane: int) -> int | None:
    """The exit of `lane` whose heading changes least (None at a dead end)."""
    exits = index.exits[lane]
    if not exits:
        return None
    end = index.heading_at(lane, float(index.lane_lengths[lane]))
    return min(exits, key=lambda e: abs(float(wrap_angle(index.heading_at(e, 0.0) - end))))


def continued(index: MapIndex, lanes: list[int] | tuple[int, ...], start: float, length: float) -> list[int]:
    """`lanes` followed by the straightest exits until they cover `length` m from `start` on the first (or the lane
    graph ends or loops): the lanes `route` draws."""
    chain = list(lanes)
    done = float(index.lane_lengths[chain[0]]) - start + sum(float(index.lane_lengths[lane]) for lane in chain[1:])
    seen = set(chain)
    while done < length:
        nxt = straightest_exit(index, chain[-1]) if index.has_connectivity else None
        if nxt is None or nxt in seen:
            break
        chain.append(nxt)
        done += float(index.lane_lengths[nxt])
        seen.add(nxt)
    return chain


def chain_path(index: MapIndex, lanes: list[int] | tuple[int, ...], start: float) -> np.ndarray:
    """The centreline along `lanes` from `start` on the first to the end of the last."""
    return join([lane_piece(index, lanes[0], start)] + [lane_piece(index, lane) for lane in lanes[1:]])


def route(index: MapIndex, lanes: list[int] | tuple[int, ...], start: float, length: float) -> np.ndarray:
    """The centreline along `lanes` from `start` on the first, continued by the straightest exits until `length` m."""
    return chain_path(index, continued(index, lanes, start, length), start)[: int(length / ROUTE_SPACING) + 2]


def straight_line(xy: np.ndarray, heading: float, length: float) -> np.ndarray:
    """The line of `length` m from `xy` along `heading`, a point every `ROUTE_SPACING` m."""
    forward = np.array([math.cos(heading), math.sin(heading)])
    return xy[None] + np.arange(0.0, length, ROUTE_SPACING)[:, None] * forward[None]
