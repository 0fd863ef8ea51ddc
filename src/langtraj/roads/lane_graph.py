"""What `MapIndex.build` derives from the map's lanes: symmetric lane links (from geometry where the map gives none),
neighbour spans, ending lanes, junction lanes from geometry and distances to the next junction (docs/interdrive.md,
'Single-agent labels')."""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass

import numpy as np

from langtraj.angles import wrap_angle
from langtraj.roads.segments import SegmentSet, arc_lengths
from langtraj.scenario.model import MapFeature

JUNCTION_CROSSING_ANGLE = math.radians(30.0)
JUNCTION_CROSSING_DISTANCE_M = 0.6
JUNCTION_END_MARGIN_M = 1.5
JUNCTION_TURN_ANGLE = math.radians(60.0)
JUNCTION_TURN_MAX_LENGTH_M = 40.0
JUNCTION_DISTANCE_CAP_M = 500.0
LINK_GAP_M = 1.0
"""A lane whose start lies within this distance of another's end continues it, in a map that links no lanes."""
LINK_MAX_ANGLE = math.radians(45.0)
"""... and only when their headings there agree within this angle."""


@dataclass(frozen=True)
class _NeighborSpan:
    """A neighbour lane along stations [start, end] of a lane."""

    lane: int
    start: float
    end: float


def _symmetric_links(
    exits: tuple[tuple[int, ...], ...], entries: tuple[tuple[int, ...], ...]
) -> tuple[tuple[tuple[int, ...], ...], tuple[tuple[int, ...], ...]]:
    """Exit and entry lists completed from each other (a source may fill only one side)."""
    ex = [set(e) for e in exits]
    en = [set(e) for e in entries]
    for lane, outs in enumerate(exits):
        for nxt in outs:
            en[nxt].add(lane)
    for lane, ins in enumerate(entries):
        for prev in ins:
            ex[prev].add(lane)
    return tuple(tuple(sorted(e)) for e in ex), tuple(tuple(sorted(e)) for e in en)


def _geometric_links(lanes: list[MapFeature]) -> tuple[tuple[int, ...], ...]:
    """Each lane's exits from geometry (nuScenes maps as ScenarioNet converts them link no lanes): the lanes that
    start within `LINK_GAP_M` of its end, heading within `LINK_MAX_ANGLE` of its end's heading."""
    usable = [len(f.points) >= 2 for f in lanes]
    if not any(usable):
        return tuple(() for _ in lanes)
    ends = np.array([f.points[-1, :2] if ok else (np.nan, np.nan) for f, ok in zip(lanes, usable, strict=True)])
    starts = np.array([f.points[0, :2] if ok else (np.nan, np.nan) for f, ok in zip(lanes, usable, strict=True)])

    def heading(points: np.ndarray, at_end: bool) -> float:
        a, b = (points[-2], points[-1]) if at_end else (points[0], points[1])
        return math.atan2(b[1] - a[1], b[0] - a[0])

    end_heading = np.array([heading(f.points, True) if ok else np.nan for f, ok in zip(lanes, usable, strict=True)])
    start_heading = np.array([heading(f.points, False) if ok else np.nan for f, ok in zip(lanes, usable, strict=True)])
    gap = np.linalg.norm(ends[:, None] - starts[None], axis=-1)  # [from, to]
    turn = np.abs(wrap_angle(end_heading[:, None] - start_heading[None]))
    linked = (gap <= LINK_GAP_M) & (turn <= LINK_MAX_ANGLE)
    np.fill_diagonal(linked, False)
    return tuple(tuple(int(j) for j in np.flatnonzero(row)) for row in linked)


def _neighbor_spans(
    lanes: list[MapFeature], index: dict[int, int]
) -> tuple[tuple[tuple[_NeighborSpan, ...], ...], tuple[tuple[_NeighborSpan, ...], ...]]:
    """Left and right neighbour spans (in stations) of each lane, completed with the reverse relations."""
    left: list[list[_NeighborSpan]] = [[] for _ in lanes]
    right: list[list[_NeighborSpan]] = [[] for _ in lanes]
    stations = [arc_lengths(f.points) if len(f.points) else np.zeros(1) for f in lanes]
    for i, feature in enumerate(lanes):
        for side, mirror, neighbors in ((left, right, feature.left_neighbors), (right, left, feature.right_neighbors)):
            for nb in neighbors:
                j = index.get(nb.feature_id)
                if j is None:
                    continue
                side[i].append(_NeighborSpan(j, *_station_range(stations[i], nb.self_start_index, nb.self_end_index)))
                span = _station_range(stations[j], nb.neighbor_start_index, nb.neighbor_end_index)
                if not any(s.lane == i for s in mirror[j]):
                    mirror[j].append(_NeighborSpan(i, *span))
    return tuple(tuple(s) for s in left), tuple(tuple(s) for s in right)


def _ending_lanes(
    exits: tuple[tuple[int, ...], ...],
    left: tuple[tuple[_NeighborSpan, ...], ...],
    right: tuple[tuple[_NeighborSpan, ...], ...],
) -> np.ndarray:
    """bool [L]: lanes without exit lanes beside a map neighbour that has some, i.e. lanes that end where the
    road goes on (an acceleration lane, a lane drop). A map cut across the road leaves both without exits."""
    ending = np.zeros(len(exits), bool)
    for lane, outs in enumerate(exits):
        if not outs:
            ending[lane] = any(exits[s.lane] for s in (*left[lane], *right[lane]))
    return ending


def _station_range(stations: np.ndarray, start: int, end: int) -> tuple[float, float]:
    last = len(stations) - 1
    lo, hi = sorted((int(np.clip(start, 0, last)), int(np.clip(end, 0, last))))
    return float(stations[lo]), float(stations[hi])


def _geometric_junctions(lanes: SegmentSet, num_lanes: int, lengths: np.ndarray) -> np.ndarray:
    """Junction lanes from geometry: centerlines crossing another at a large angle, or short sharp turns."""
    junction = np.zeros(num_lanes, bool)
    if len(lanes) == 0:
        return junction
    mid = 0.5 * (lanes.start + lanes.end)
    query, seg = lanes.candidates(mid, JUNCTION_CROSSING_DISTANCE_M)
    other = lanes.owner[seg] != lanes.owner[query]
    query, seg = query[other], seg[other]
    dist, _, station = lanes.project(mid[query], seg)
    diff = np.abs(wrap_angle(lanes.heading[query] - lanes.heading[seg]))
    folded = np.minimum(diff, np.pi - diff)
    own_station = lanes.station[query] + 0.5 * np.linalg.norm(lanes.end[query] - lanes.start[query], axis=1)
    own_len = lengths[lanes.owner[query]]
    other_len = lengths[lanes.owner[seg]]
    away = (
        (own_station > JUNCTION_END_MARGIN_M)
        & (own_station < own_len - JUNCTION_END_MARGIN_M)
        & (station > JUNCTION_END_MARGIN_M)
        & (station < other_len - JUNCTION_END_MARGIN_M)
    )
    hit = (dist <= JUNCTION_CROSSING_DISTANCE_M) & (folded >= JUNCTION_CROSSING_ANGLE) & away
    junction[lanes.owner[query[hit]]] = True
    for lane in range(num_lanes):
        segs = lanes.segments_of(lane)
        if len(segs) and lengths[lane] <= JUNCTION_TURN_MAX_LENGTH_M:
            turn = abs(float(np.sum(wrap_angle(np.diff(lanes.heading[segs])))))
            junction[lane] |= turn >= JUNCTION_TURN_ANGLE
    return junction


def _junction_distances(
    junction: np.ndarray,
    lengths: np.ndarray,
    entries: tuple[tuple[int, ...], ...],
) -> np.ndarray:
    """Distance from each lane's start along the lane graph to the start of the nearest junction lane ahead
    (Dijkstra backwards from the junction lanes, capped at `JUNCTION_DISTANCE_CAP_M`; inf beyond)."""
    dist = np.full(len(junction), np.inf)
    heap = [(0.0, int(j)) for j in np.flatnonzero(junction)]
    for _, j in heap:
        dist[j] = 0.0
    heapq.heapify(heap)
    while heap:
        d, lane = heapq.heappop(heap)
        if d > dist[lane]:
            continue
        for prev in entries[lane]:
            cand = d + lengths[prev]
            if not junction[prev] and cand < dist[prev] and cand <= JUNCTION_DISTANCE_CAP_M:
                dist[prev] = cand
                heapq.heappush(heap, (cand, prev))
    return dist
