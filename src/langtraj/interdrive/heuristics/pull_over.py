"""Where a pull-over starts, for `PullingOverRule`: sideways motion across the last lane toward the kerb or the
road side (docs/interdrive.md, 'Single-agent labels')."""

from __future__ import annotations

import numpy as np

from langtraj.angles import wrap_angle
from langtraj.interdrive.heuristics.context import LabelContext
from langtraj.roads import MapIndex


def _lane_frame(index: MapIndex, lane: int, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Signed lateral offset (left positive), station and centerline heading of each point [N, 2] at the nearest
    segment of `lane`. The offset is measured from that segment's line, so a point past the lane's start (on the
    lane before a split) keeps its sideways offset instead of its distance to the lane's end point."""
    segs = index.lanes.segments_of(lane)
    rows = np.arange(len(xy))
    dist, _, station = index.lanes.project(np.repeat(xy, len(segs), axis=0), np.tile(segs, len(xy)))
    pick = dist.reshape(len(xy), len(segs)).argmin(axis=1)
    best = segs[pick]
    heading = index.lanes.heading[best]
    rel = xy - index.lanes.start[best]
    lateral = np.cos(heading) * rel[:, 1] - np.sin(heading) * rel[:, 0]
    return lateral, station.reshape(len(xy), len(segs))[rows, pick], heading


def _nearest_edge_point(index: MapIndex, xy: np.ndarray, radius: float) -> np.ndarray | None:
    """The point [2] of the road edges nearest to `xy` [2], or None when none lies within `radius`."""
    point = np.asarray(xy, np.float64).reshape(1, 2)
    query, seg = index.edges.candidates(point, radius)
    if not len(seg):
        return None
    dist, _, _ = index.edges.project(point[query], seg)
    if dist.min() > radius:
        return None
    best = int(seg[np.argmin(dist)])
    start, end = index.edges.start[best], index.edges.end[best]
    along = end - start
    t = float(np.clip(np.dot(point[0] - start, along) / max(float(np.dot(along, along)), 1e-12), 0.0, 1.0))
    return start + t * along


def _pull_over_start(ctx: LabelContext, a: int, floor: int, stop: int) -> int | str | None:
    """The future step where vehicle `a`'s pull-over into the stop beginning at future step `stop` starts, a reason
    why it cannot be decided, or None when the stop is not a pull-over (see `PullingOverRule`). Sideways motion is
    looked for over future steps from `floor` on (the end of an earlier stop)."""
    cfg, index = ctx.config, ctx.map_index
    first = max(floor, stop - ctx.steps(cfg.pull_over_lookback_s))
    lanes = ctx.vehicle_lanes.lane[a, first : stop + 1]
    matched = np.flatnonzero(lanes >= 0)
    if not len(matched):
        return None  # off every lane all along: off the main roads, not pulling over from a lane
    lane = int(lanes[matched[-1]])  # the lane it drove in last: sideways motion is measured across it
    if index.is_junction[lane]:
        return None  # stopped in a junction
    xy = ctx.fut(ctx.kin.xy)[a, first : stop + 1]
    lateral, station, heading = _lane_frame(index, lane, xy)
    # Only the steps since the vehicle last turned away from that lane or drove on a junction lane count: offsets
    # from another road (before a turn) say nothing about moving sideways on this one.
    aligned = np.abs(wrap_angle(ctx.fut(ctx.kin.yaw)[a, first : stop + 1] - heading)) <= cfg.lane_match_max_heading
    on_junction = (lanes >= 0) & index.is_junction[np.maximum(lanes, 0)]
    broken = np.flatnonzero(~aligned | on_junction | ~ctx.future[a, first : stop + 1])
    begin = int(broken[-1]) + 1 if len(broken) else 0
    if begin >= len(xy) - 1:
        return None
    lat = lateral[begin:]
    to_right, to_left = float(lat.max() - lat[-1]), float(lat[-1] - lat.min())
    side = -1.0 if to_right >= to_left else 1.0  # toward the road side: right (-1) or left (+1) of the lane
    shift = max(to_right, to_left)
    if shift < cfg.pull_over_min_lateral or side * float(lat[-1]) < cfg.pull_over_min_lane_offset:
        return None  # no sideways move, or back on (or short of) a lane centre: a lane change, a queue
    if index.distance_to_junction(lane, float(station[-1])) <= cfg.pull_over_junction_distance:
        return None  # stopped at a junction
    if index.has_road_edges:
        kerb = _nearest_edge_point(index, xy[-1], cfg.pull_over_max_edge_distance)
        if kerb is None:
            return None  # not at the kerb
        if side * (float(_lane_frame(index, lane, kerb[None])[0][0]) - float(lat[-1])) < 0.0:
            return None  # the nearest edge lies on the other side: it moved away from the kerb (to the median)
    else:
        position = index.lane_position(lane, float(station[-1]))
        if position == "unknown":
            return "the map has no road edges and no lane neighbour lists to tell the road side"
        if position not in ("single", "rightmost" if side < 0 else "leftmost"):
            return None  # another lane lies on that side: not the road side
    toward = side * lat
    settled = np.flatnonzero(toward <= toward.min() + cfg.pull_over_start_offset)
    return first + begin + int(settled[-1])
