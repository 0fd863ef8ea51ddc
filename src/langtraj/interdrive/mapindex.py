"""Map queries and the lane primitives of the heuristic labeler and the interaction detector, built once per scene
over a `RoadMap` (docs/interdrive.md describes both labelers).

Lanes and road edges are resampled to short segments (at most `SEGMENT_SPACING_M` long) and bucketed in a
uniform grid, so a batch of positions is matched to its nearest segments by vectorised numpy (no scipy).

What each query relies on, and what it falls back to (each `*_source` attribute names it):
- junction lanes: `MapFeature.interpolating` when any lane of the map sets it (WOMD v1.1+, synthesized maps);
  otherwise geometry: a lane whose centerline crosses another lane's centerline at 30 degrees or more
  (away from both lanes' ends, so lanes that merge or fan out from a shared point do not count), or a short
  lane that turns sharply (at least 60 degrees within 40 m).
- lane neighbours: `left_neighbors` / `right_neighbors` where the map has any; optionally (`infer_neighbors`)
  geometry: a same-direction lane whose centerline runs 2.5-4.5 m beside this one; otherwise none. The detector
  asks per lane pair instead (`neighbor_side` with `per_lane`).
- parked vehicles: `parked_decision`, whether a vehicle standing all window is at the road side.
- lane changes: both labelers report them as `LaneChange`.
- lane connectivity (distance to the next junction): `exit_lanes` / `entry_lanes` only.
- crosswalks and road edges: the `CROSSWALK` polygons and `ROAD_EDGE_*` polylines, where the map has any.
"""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass
from functools import cached_property
from typing import Literal

import numpy as np

from langtraj.angles import wrap_angle
from langtraj.scenario.model import MapFeature, RoadMap
from langtraj.scenario.types import MapFeatureType

SEGMENT_SPACING_M = 1.0
"""Longest segment after resampling lane and edge polylines (m)."""

GRID_CELL_M = 3.0
"""Side of a grid cell of the segment index (m)."""

JUNCTION_CROSSING_ANGLE = math.radians(30.0)
JUNCTION_CROSSING_DISTANCE_M = 0.6
JUNCTION_END_MARGIN_M = 1.5
JUNCTION_TURN_ANGLE = math.radians(60.0)
JUNCTION_TURN_MAX_LENGTH_M = 40.0
NEIGHBOR_MIN_OFFSET_M = 2.5
NEIGHBOR_MAX_OFFSET_M = 4.5
NEIGHBOR_BAND_M = (NEIGHBOR_MIN_OFFSET_M, NEIGHBOR_MAX_OFFSET_M)
"""Offset between a lane and a geometric neighbour lane, measured at a point on both (m)."""
NEIGHBOR_MAX_HEADING_DIFF = math.radians(20.0)
NEIGHBOR_STATION_TOLERANCE_M = 3.0
JUNCTION_DISTANCE_CAP_M = 500.0

LanePosition = Literal["leftmost", "middle", "rightmost", "single", "unknown"]
Side = Literal["left", "right"]
DRIVABLE_LANE_TYPES = (MapFeatureType.LANE_UNKNOWN, MapFeatureType.LANE_FREEWAY, MapFeatureType.LANE_SURFACE_STREET)


def _resample(points: np.ndarray, spacing: float) -> np.ndarray:
    """A 2-D polyline resampled at equal steps of at most `spacing`; duplicates dropped; [0, 2] if degenerate."""
    xy = points[:, :2]
    if len(xy) >= 2:
        keep = np.concatenate([[True], np.linalg.norm(np.diff(xy, axis=0), axis=1) > 1e-6])
        xy = xy[keep]
    if len(xy) < 2:
        return np.zeros((0, 2))
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(xy, axis=0), axis=1))])
    num = max(1, math.ceil(s[-1] / spacing))
    s_new = np.linspace(0.0, s[-1], num + 1)
    return np.stack([np.interp(s_new, s, xy[:, 0]), np.interp(s_new, s, xy[:, 1])], axis=1)


def arc_lengths(points: np.ndarray) -> np.ndarray:
    """Arc length at each point of a polyline."""
    steps = np.linalg.norm(np.diff(points[:, :2], axis=0), axis=1)
    return np.concatenate([[0.0], np.cumsum(steps)])


@dataclass(frozen=True, eq=False)
class SegmentSet:
    """Short segments of several polylines in a uniform grid, for radius queries by many points at once."""

    start: np.ndarray  # float64 [G, 2]
    end: np.ndarray  # float64 [G, 2]
    owner: np.ndarray  # int64 [G], index of the polyline the segment belongs to
    station: np.ndarray  # float64 [G], arc length of the segment start along its polyline
    heading: np.ndarray  # float64 [G]
    owner_first: np.ndarray  # int64 [P], first segment of each polyline
    owner_stop: np.ndarray  # int64 [P], one past its last segment
    origin: np.ndarray  # float64 [2]
    shape: tuple[int, int]
    sorted_keys: np.ndarray  # int64 [G], grid cell of each segment, sorted
    order: np.ndarray  # int64 [G], segment index of each sorted key

    @classmethod
    def build(cls, polylines: list[np.ndarray], spacing: float = SEGMENT_SPACING_M) -> SegmentSet:
        """Resample `polylines` and index their segments; an empty or degenerate polyline gets no segments."""
        starts, ends, owners, stations = [], [], [], []
        first = np.zeros(len(polylines), np.int64)
        stop = np.zeros(len(polylines), np.int64)
        count = 0
        for i, line in enumerate(polylines):
            pts = _resample(line, spacing)
            first[i] = count
            if len(pts) >= 2:
                starts.append(pts[:-1])
                ends.append(pts[1:])
                owners.append(np.full(len(pts) - 1, i, np.int64))
                stations.append(arc_lengths(pts)[:-1])
                count += len(pts) - 1
            stop[i] = count
        if count == 0:
            empty = np.zeros((0, 2))
            return cls(empty, empty, np.zeros(0, np.int64), np.zeros(0), np.zeros(0), first, stop, np.zeros(2), (0, 0),
                       np.zeros(0, np.int64), np.zeros(0, np.int64))  # fmt: skip
        start, end = np.concatenate(starts), np.concatenate(ends)
        delta = end - start
        mid = 0.5 * (start + end)
        origin = mid.min(axis=0) - GRID_CELL_M
        cells = np.floor((mid - origin) / GRID_CELL_M).astype(np.int64)
        shape = (int(cells[:, 0].max()) + 2, int(cells[:, 1].max()) + 2)
        keys = cells[:, 0] * shape[1] + cells[:, 1]
        order = np.argsort(keys, kind="stable")
        return cls(
            start,
            end,
            np.concatenate(owners),
            np.concatenate(stations),
            np.arctan2(delta[:, 1], delta[:, 0]),
            first,
            stop,
            origin,
            shape,
            keys[order],
            order,
        )

    def __len__(self) -> int:
        return len(self.owner)

    def candidates(self, xy: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
        """Pairs (query index, segment index) of every segment that may lie within `radius` of a query point."""
        if len(self) == 0 or len(xy) == 0:
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        reach = math.ceil((radius + SEGMENT_SPACING_M / 2) / GRID_CELL_M)
        cells = np.floor((xy - self.origin) / GRID_CELL_M).astype(np.int64)
        offsets = np.arange(-reach, reach + 1)
        cx = (cells[:, 0:1] + offsets[None, :])[:, :, None]
        cy = (cells[:, 1:2] + offsets[None, :])[:, None, :]
        inside = (cx >= 0) & (cx < self.shape[0]) & (cy >= 0) & (cy < self.shape[1])
        keys = np.where(inside, cx * self.shape[1] + cy, -1).reshape(len(xy), -1)
        lo = np.searchsorted(self.sorted_keys, keys, "left").ravel()
        hi = np.searchsorted(self.sorted_keys, keys, "right").ravel()
        counts = hi - lo
        total = int(counts.sum())
        query = np.repeat(np.repeat(np.arange(len(xy)), keys.shape[1]), counts)
        within = np.arange(total) - np.repeat(np.cumsum(counts) - counts, counts)
        return query, self.order[np.repeat(lo, counts) + within]

    def project(self, xy: np.ndarray, segments: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Distance, signed lateral offset (left of the segment positive) and station of each point on its segment."""
        a, b = self.start[segments], self.end[segments]
        d = b - a
        length = np.maximum(np.linalg.norm(d, axis=1), 1e-9)
        rel = xy - a
        t = np.clip((rel * d).sum(axis=1) / length**2, 0.0, 1.0)
        dist = np.linalg.norm(rel - t[:, None] * d, axis=1)
        side = np.where(d[:, 0] * rel[:, 1] - d[:, 1] * rel[:, 0] >= 0, 1.0, -1.0)
        return dist, side * dist, self.station[segments] + t * length

    def segments_of(self, owner: int) -> np.ndarray:
        """Segment indices of polyline `owner`."""
        return np.arange(self.owner_first[owner], self.owner_stop[owner])


def _best_per_query(query: np.ndarray, cost: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each query with at least one pair, the position (into the pair arrays) of its cheapest pair."""
    if len(query) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    order = np.lexsort((cost, query))
    q_sorted = query[order]
    first = np.concatenate([[True], q_sorted[1:] != q_sorted[:-1]])
    return q_sorted[first], order[first]


@dataclass(frozen=True, eq=False)
class LaneMatch:
    """Best lane of each query point; `lane` is an index into `MapIndex.lane_ids`, -1 where none matched."""

    lane: np.ndarray  # int64 [N]
    distance: np.ndarray  # float64 [N], distance to the centerline, inf where none
    lateral: np.ndarray  # float64 [N], signed offset from the centerline (left positive), nan where none
    station: np.ndarray  # float64 [N], arc length along the lane, nan where none
    heading: np.ndarray  # float64 [N], centerline heading there, nan where none

    @property
    def matched(self) -> np.ndarray:
        return self.lane >= 0


@dataclass(frozen=True)
class LaneChange:
    """Agent index `agent` switches from lane `from_lane` to neighbour lane `to_lane` (map feature ids, -1 where
    unknown) at window step `switch`, over window steps [start, end).

    The detector fills only these; the heuristic labeler also the `side` of the new lane, the `lateral`
    displacement across the lanes (m, left positive) and the lane positions left and entered."""

    agent: int
    from_lane: int
    to_lane: int
    switch: int
    start: int
    end: int
    side: Side | None = None
    lateral: float | None = None
    from_position: LanePosition = "unknown"
    to_position: LanePosition = "unknown"


@dataclass(frozen=True)
class _NeighborSpan:
    """A neighbour lane along stations [start, end] of a lane."""

    lane: int
    start: float
    end: float


@dataclass(frozen=True, eq=False)
class MapIndex:
    """Per-scene lane, junction, neighbour, crosswalk and road-edge queries (see the module docstring)."""

    lane_ids: np.ndarray  # int64 [L], feature ids of the lanes (drivable and bike lanes), in map order
    lane_features: tuple[MapFeature, ...]  # [L], the lanes themselves
    lane_types: np.ndarray  # int8 [L], MapFeatureType values
    lane_lengths: np.ndarray  # float64 [L]
    lanes: SegmentSet
    edges: SegmentSet
    crosswalks: tuple[np.ndarray, ...]
    is_junction: np.ndarray  # bool [L]
    junction_source: Literal["map", "geometry", "none"]
    neighbor_source: Literal["map", "geometry", "none"]
    has_connectivity: bool
    exits: tuple[tuple[int, ...], ...]
    entries: tuple[tuple[int, ...], ...]
    left_spans: tuple[tuple[_NeighborSpan, ...], ...]
    right_spans: tuple[tuple[_NeighborSpan, ...], ...]
    junction_distance_from_start: np.ndarray  # float64 [L], along the lane graph to the next junction lane
    is_ending: np.ndarray  # bool [L], a lane that ends beside a neighbour that goes on (see `_ending_lanes`)

    @classmethod
    def build(cls, road_map: RoadMap, infer_neighbors: bool = False) -> MapIndex:
        """Index `road_map`; with `infer_neighbors`, a map without neighbour lists gets them from geometry."""
        lane_feats = road_map.lanes
        index = {f.id: i for i, f in enumerate(lane_feats)}
        lanes = SegmentSet.build([f.points for f in lane_feats])
        lengths = np.array([arc_lengths(f.points)[-1] if len(f.points) > 1 else 0.0 for f in lane_feats])
        exits = tuple(tuple(index[e] for e in f.exit_lanes if e in index) for f in lane_feats)
        entries = tuple(tuple(index[e] for e in f.entry_lanes if e in index) for f in lane_feats)
        exits, entries = _symmetric_links(exits, entries)
        has_connectivity = any(exits)
        if any(f.interpolating for f in lane_feats):
            junction, junction_source = np.array([f.interpolating for f in lane_feats], bool), "map"
        elif lane_feats:
            junction, junction_source = _geometric_junctions(lanes, len(lane_feats), lengths), "geometry"
        else:
            junction, junction_source = np.zeros(0, bool), "none"
        left, right = _neighbor_spans(lane_feats, index)
        inferred = "geometry" if infer_neighbors and lane_feats else "none"
        neighbor_source = "map" if any(left) or any(right) else inferred
        edge_feats = road_map.road_edges
        crosswalks = tuple(f.points[:, :2] for f in road_map.of_type(MapFeatureType.CROSSWALK) if len(f.points) >= 3)
        return cls(
            lane_ids=np.array([f.id for f in lane_feats], np.int64),
            lane_features=tuple(lane_feats),
            lane_types=np.array([f.type for f in lane_feats], np.int8),
            lane_lengths=lengths,
            lanes=lanes,
            edges=SegmentSet.build([f.points for f in edge_feats]),
            crosswalks=crosswalks,
            is_junction=junction,
            junction_source=junction_source,
            neighbor_source=neighbor_source,
            has_connectivity=has_connectivity,
            exits=exits,
            entries=entries,
            left_spans=left,
            right_spans=right,
            junction_distance_from_start=_junction_distances(junction, lengths, entries),
            is_ending=_ending_lanes(exits, left, right),
        )

    # ------------------------------------------------------------------ what the map has
    @property
    def num_lanes(self) -> int:
        return len(self.lane_ids)

    @property
    def has_lanes(self) -> bool:
        return len(self.lanes) > 0

    @property
    def has_road_edges(self) -> bool:
        return len(self.edges) > 0

    @property
    def has_crosswalks(self) -> bool:
        return bool(self.crosswalks)

    @cached_property
    def lane_row(self) -> dict[int, int]:
        """Index into `lane_ids` of each lane's feature id."""
        return {int(lane): i for i, lane in enumerate(self.lane_ids)}

    @cached_property
    def is_drivable(self) -> np.ndarray:
        """bool [L]: lanes cars use (not bike lanes)."""
        return np.isin(self.lane_types, [int(t) for t in DRIVABLE_LANE_TYPES])

    # ------------------------------------------------------------------ lane matching
    def match_lanes(
        self,
        xy: np.ndarray,
        heading: np.ndarray | None = None,
        *,
        radius: float,
        max_heading_diff: float = math.pi,
        heading_weight: float = 2.0,
        drivable_only: bool = True,
        exclude_junctions: bool = False,
    ) -> LaneMatch:
        """The best lane of each point within `radius`: least distance plus `heading_weight` (m/rad) times
        the heading disagreement, among lanes within `max_heading_diff` of `heading` (any lane without one);
        `drivable_only` leaves out bike lanes, `exclude_junctions` junction lanes."""
        xy = np.asarray(xy, np.float64).reshape(-1, 2)
        num = len(xy)
        out = LaneMatch(
            np.full(num, -1, np.int64), np.full(num, np.inf), np.full(num, np.nan), np.full(num, np.nan),
            np.full(num, np.nan),
        )  # fmt: skip
        query, seg = self.lanes.candidates(xy, radius)
        if drivable_only and len(seg):
            keep = self.is_drivable[self.lanes.owner[seg]]
            query, seg = query[keep], seg[keep]
        if exclude_junctions and len(seg):
            keep = ~self.is_junction[self.lanes.owner[seg]]
            query, seg = query[keep], seg[keep]
        dist, lateral, station = self.lanes.project(xy[query], seg)
        keep = dist <= radius
        cost = dist
        if heading is not None:
            diff = np.abs(wrap_angle(np.asarray(heading, np.float64).ravel()[query] - self.lanes.heading[seg]))
            keep &= diff <= max_heading_diff
            cost = dist + heading_weight * diff
        query, seg, dist, lateral, station, cost = (v[keep] for v in (query, seg, dist, lateral, station, cost))
        rows, best = _best_per_query(query, cost)
        out.lane[rows] = self.lanes.owner[seg[best]]
        out.distance[rows] = dist[best]
        out.lateral[rows] = lateral[best]
        out.station[rows] = station[best]
        out.heading[rows] = self.lanes.heading[seg[best]]
        return out

    def project_to_lane(self, lane: int, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Station and signed lateral offset of each point relative to lane `lane` (its nearest segment)."""
        xy = np.asarray(xy, np.float64).reshape(-1, 2)
        segs = self.lanes.segments_of(lane)
        if len(segs) == 0:
            return np.full(len(xy), np.nan), np.full(len(xy), np.nan)
        query = np.repeat(np.arange(len(xy)), len(segs))
        seg = np.tile(segs, len(xy))
        dist, lateral, station = self.lanes.project(xy[query], seg)
        best = dist.reshape(len(xy), len(segs)).argmin(axis=1) + np.arange(len(xy)) * len(segs)
        return station[best], lateral[best]

    def lanes_crossing(self, xy: np.ndarray, heading: np.ndarray, *, radius: float, min_angle: float) -> np.ndarray:
        """bool [N]: some lane centerline within `radius` of the point runs at `min_angle` or more to `heading`
        (folded to [0, pi/2], so direction along the lane does not matter)."""
        xy = np.asarray(xy, np.float64).reshape(-1, 2)
        query, seg = self.lanes.candidates(xy, radius)
        dist, _, _ = self.lanes.project(xy[query], seg)
        diff = np.abs(wrap_angle(np.asarray(heading, np.float64)[query] - self.lanes.heading[seg]))
        folded = np.minimum(diff, np.pi - diff)
        hit = (dist <= radius) & (folded >= min_angle)
        out = np.zeros(len(xy), bool)
        out[query[hit]] = True
        return out

    # ------------------------------------------------------------------ neighbours and lane position
    def lane_position(self, lane: int, station: float, with_ending: bool = False) -> LanePosition:
        """Position of `lane` among its same-direction neighbours at `station`: "unknown" where the map has no
        neighbour information (and none is inferred) or the lane is a junction lane. Only lanes of the same
        kind count: a bike lane beside the rightmost car lane does not make that lane a middle one; nor does a
        lane that ends beside it (an acceleration lane, a lane drop: `is_ending`), unless this lane ends too or
        `with_ending` (a change into or out of such a lane is placed among all the lanes there)."""
        if self.neighbor_source == "none" or self.is_junction[lane]:
            return "unknown"
        if self.neighbor_source == "map":
            left = tuple(s for s in self.left_spans[lane] if self._counts_beside(lane, s.lane, with_ending))
            right = tuple(s for s in self.right_spans[lane] if self._counts_beside(lane, s.lane, with_ending))
            has_left, has_right = _covers(left, station), _covers(right, station)
        else:
            has_left, has_right = self._geometric_sides(lane, station, with_ending)
        if has_left and has_right:
            return "middle"
        if has_left:
            return "rightmost"
        return "leftmost" if has_right else "single"

    def _counts_beside(self, lane: int, other: int, with_ending: bool) -> bool:
        """Whether lane `other` beside `lane` counts for `lane`'s position (see `lane_position`)."""
        drivable = self.is_drivable
        ending = with_ending or self.is_ending[lane] or not self.is_ending[other]
        return bool(drivable[other] == drivable[lane] and ending)

    def neighbor_side(
        self,
        lane_from: int,
        lane_to: int,
        xy: np.ndarray | None = None,
        *,
        band: tuple[float, float] = NEIGHBOR_BAND_M,
        per_lane: bool = False,
    ) -> Side | None:
        """Whether `lane_to` is a left or right neighbour of `lane_from` near point `xy` (None if neither): the
        neighbour-lane search of both labelers.

        By default (the heuristic labeler) the map decides as a whole: with map neighbours, the neighbour lists of
        both lanes and of their predecessors and successors count (neighbour lanes are often split at other
        points); with inferred neighbours, geometry at `xy` decides (`geometric_side`, lanes `band` apart).
        With `per_lane` (the interaction detector) each pair of lanes decides: listed in either's neighbour list,
        they are neighbours; when either lists others, or `lane_from` names `lane_to` an exit or entry lane, they are
        not; otherwise when the middle point of `lane_to` lies `band` from the nearest point of `lane_from` (no
        `xy`)."""
        if per_lane:
            return self._pair_side(lane_from, lane_to, band)
        if self.neighbor_source == "none":
            return None
        if self.neighbor_source == "geometry":
            return self.geometric_side(lane_from, lane_to, xy, band=band)
        near = {lane_from, *self.entries[lane_from], *self.exits[lane_from]}
        for side, spans in (("left", self.left_spans), ("right", self.right_spans)):
            beside = {s.lane for x in near for s in spans[x]}
            beside |= {c for y in beside for c in (*self.exits[y], *self.entries[y])}
            if lane_to in beside:
                return side  # type: ignore[return-value]
        return None

    def _pair_side(self, lane_from: int, lane_to: int, band: tuple[float, float]) -> Side | None:
        """`neighbor_side` with `per_lane`."""
        for side, spans in (("left", self.left_spans), ("right", self.right_spans)):
            if any(s.lane == lane_to for s in spans[lane_from]):  # spans hold both lanes' lists
                return side  # type: ignore[return-value]
        a, b = self.lane_features[lane_from], self.lane_features[lane_to]
        if a.left_neighbors or a.right_neighbors or b.left_neighbors or b.right_neighbors:
            return None
        if b.id in a.exit_lanes or b.id in a.entry_lanes:
            return None
        points = a.points[:, :2]
        mid = b.points[len(b.points) // 2, :2]
        gaps = np.linalg.norm(points - mid, axis=1)
        k = int(np.argmin(gaps))
        if not band[0] <= float(gaps[k]) <= band[1]:
            return None
        along = points[min(k + 1, len(points) - 1)] - points[max(k - 1, 0)]
        rel = mid - points[k]
        return "left" if along[0] * rel[1] - along[1] * rel[0] >= 0 else "right"

    def geometric_side(
        self, lane_from: int, lane_to: int, xy: np.ndarray, band: tuple[float, float] = NEIGHBOR_BAND_M
    ) -> Side | None:
        """Side of `lane_to` from `lane_from` at point `xy` when they run parallel `band` (2.5-4.5 m) apart there."""
        point = np.asarray(xy, np.float64).reshape(1, 2)
        s_from, lat_from = self.project_to_lane(lane_from, point)
        s_to, lat_to = self.project_to_lane(lane_to, point)
        if not (np.isfinite(lat_from[0]) and np.isfinite(lat_to[0])):
            return None
        diff = abs(float(wrap_angle(self.heading_at(lane_from, s_from[0]) - self.heading_at(lane_to, s_to[0]))))
        offset = float(lat_from[0] - lat_to[0])
        if diff > NEIGHBOR_MAX_HEADING_DIFF or not band[0] <= abs(offset) <= band[1]:
            return None
        return "left" if offset > 0 else "right"

    def heading_at(self, lane: int, station: float) -> float:
        """Centerline heading of `lane` at `station`."""
        segs = self.lanes.segments_of(lane)
        i = int(np.clip(np.searchsorted(self.lanes.station[segs], station, "right") - 1, 0, len(segs) - 1))
        return float(self.lanes.heading[segs[i]])

    def point_at(self, lane: int, station: float) -> np.ndarray:
        """Centerline point of `lane` at `station` [2]."""
        segs = self.lanes.segments_of(lane)
        i = int(np.clip(np.searchsorted(self.lanes.station[segs], station, "right") - 1, 0, len(segs) - 1))
        seg = segs[i]
        direction = self.lanes.end[seg] - self.lanes.start[seg]
        t = (station - self.lanes.station[seg]) / max(float(np.linalg.norm(direction)), 1e-9)
        return self.lanes.start[seg] + np.clip(t, 0.0, 1.0) * direction

    def _geometric_sides(self, lane: int, station: float, with_ending: bool = False) -> tuple[bool, bool]:
        """Whether a same-direction lane runs 2.5-4.5 m to the left / right of `lane` at `station`."""
        point = self.point_at(lane, station)[None]
        heading = self.heading_at(lane, station)
        _, seg = self.lanes.candidates(point, NEIGHBOR_MAX_OFFSET_M)
        owner = self.lanes.owner[seg]
        ending = with_ending or self.is_ending[lane]
        counts = (self.is_drivable[owner] == self.is_drivable[lane]) & (ending | ~self.is_ending[owner])
        seg = seg[(owner != lane) & counts]
        _, lateral, _ = self.lanes.project(np.repeat(point, len(seg), axis=0), seg)
        same = np.abs(wrap_angle(self.lanes.heading[seg] - heading)) <= NEIGHBOR_MAX_HEADING_DIFF
        apart = (np.abs(lateral) >= NEIGHBOR_MIN_OFFSET_M) & (np.abs(lateral) <= NEIGHBOR_MAX_OFFSET_M)
        beside = lateral[same & apart]
        # The point lies right of a lane on its left, so that lane's lateral offset of the point is negative.
        return bool((beside < 0).any()), bool((beside > 0).any())

    # ------------------------------------------------------------------ parked vehicles
    def parked_decision(
        self,
        match: LaneMatch,
        xy: np.ndarray,
        *,
        lane_offset: float | None = None,
        queue_distance: float | None = None,
        kerb_distance: float | None = None,
    ) -> tuple[bool | None, str]:
        """Whether a vehicle standing all window is parked (True / False / None = undecided), and why, from its
        lane `match` at points `xy` [N, 2] (the caller decides that it stands, and how lanes are matched).

        Undecided on a map without lanes; parked when no point matched a lane; then, at the first matched point,
        parked when at least `lane_offset` from the lane centre. Without `kerb_distance` (the detector) a vehicle
        on a lane is not parked; with it (the heuristic labeler) it is not on a junction lane or within
        `queue_distance` before one along its lane (queued), undecided where the map has no road edges, and parked
        within `kerb_distance` of a road edge."""
        if not self.has_lanes:
            return None, "the map has no lanes to tell the road side from a traffic lane"
        if not match.matched.any():
            return True, "off every lane"
        k = int(np.argmax(match.matched))
        if lane_offset is not None and abs(float(match.lateral[k])) >= lane_offset:
            return True, "beside the lane centre"
        if kerb_distance is None:
            return False, "on a lane"
        lane = int(match.lane[k])
        if self.is_junction[lane]:
            return False, "stopped in a junction lane"
        if queue_distance is not None and self.distance_to_junction(lane, float(match.station[k])) <= queue_distance:
            return False, "stopped in a lane before a junction (a queue)"
        if not self.has_road_edges:
            return None, "stopped on a lane centre and the map has no road edges to check the kerb"
        edge = float(self.distance_to_road_edge(np.asarray(xy).reshape(-1, 2)[k], kerb_distance)[0])
        return (True, "at the kerb") if edge <= kerb_distance else (False, "stopped in a traffic lane")

    # ------------------------------------------------------------------ junctions
    def distance_to_junction(self, lane: int, station: float) -> float:
        """Distance along the lane graph from `station` on `lane` to the start of the next junction lane: 0 on a
        junction lane, inf when none is reachable (or the map has no connectivity)."""
        if self.is_junction[lane]:
            return 0.0
        ahead = [self.junction_distance_from_start[e] for e in self.exits[lane]]
        return float(max(self.lane_lengths[lane] - station, 0.0) + min(ahead, default=math.inf))

    # ------------------------------------------------------------------ crosswalks and road edges
    def in_crosswalk(self, xy: np.ndarray) -> np.ndarray:
        """bool [N]: the point lies inside a crosswalk polygon."""
        xy = np.asarray(xy, np.float64).reshape(-1, 2)
        out = np.zeros(len(xy), bool)
        for polygon in self.crosswalks:
            out |= _inside_polygon(xy, polygon)
        return out

    def distance_to_road_edge(self, xy: np.ndarray, radius: float) -> np.ndarray:
        """Distance [N] of each point to the nearest road edge, inf beyond `radius` (or without road edges)."""
        xy = np.asarray(xy, np.float64).reshape(-1, 2)
        out = np.full(len(xy), np.inf)
        query, seg = self.edges.candidates(xy, radius)
        dist, _, _ = self.edges.project(xy[query], seg)
        np.minimum.at(out, query, dist)
        out[out > radius] = np.inf
        return out


def _covers(spans: tuple[_NeighborSpan, ...], station: float) -> bool:
    return any(s.start - NEIGHBOR_STATION_TOLERANCE_M <= station <= s.end + NEIGHBOR_STATION_TOLERANCE_M for s in spans)


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


def _inside_polygon(xy: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """bool [N]: even-odd point-in-polygon test."""
    inside = np.zeros(len(xy), bool)
    px, py = xy[:, 0], xy[:, 1]
    for (x1, y1), (x2, y2) in zip(polygon, np.roll(polygon, -1, axis=0), strict=True):
        if y1 == y2:
            continue
        crosses = (y1 > py) != (y2 > py)
        x_at = x1 + (py - y1) * (x2 - x1) / (y2 - y1)
        inside ^= crosses & (px < x_at)
    return inside
