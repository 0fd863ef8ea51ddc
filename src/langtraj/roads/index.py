"""`MapIndex`: the per-scene lane, junction, neighbour, crosswalk and road-edge queries over a `RoadMap` (see the
package docstring; docs/interdrive.md, 'Single-agent labels')."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import Literal

import numpy as np

from langtraj.angles import wrap_angle
from langtraj.roads.lane_graph import (
    _ending_lanes,
    _geometric_junctions,
    _geometric_links,
    _junction_distances,
    _neighbor_spans,
    _NeighborSpan,
    _symmetric_links,
)
from langtraj.roads.records import LaneMatch, LanePosition, Side
from langtraj.roads.segments import SegmentSet, _best_per_query, arc_lengths
from langtraj.scenario.model import MapFeature, RoadMap
from langtraj.scenario.types import MapFeatureType

NEIGHBOR_MIN_OFFSET_M = 2.5
NEIGHBOR_MAX_OFFSET_M = 4.5
NEIGHBOR_BAND_M = (NEIGHBOR_MIN_OFFSET_M, NEIGHBOR_MAX_OFFSET_M)
"""Offset between a lane and a geometric neighbour lane, measured at a point on both (m)."""
NEIGHBOR_MAX_HEADING_DIFF = math.radians(20.0)
NEIGHBOR_STATION_TOLERANCE_M = 3.0

DRIVABLE_LANE_TYPES = (MapFeatureType.LANE_UNKNOWN, MapFeatureType.LANE_FREEWAY, MapFeatureType.LANE_SURFACE_STREET)


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
    connectivity_source: Literal["map", "geometry", "none"]
    exits: tuple[tuple[int, ...], ...]
    entries: tuple[tuple[int, ...], ...]
    left_spans: tuple[tuple[_NeighborSpan, ...], ...]
    right_spans: tuple[tuple[_NeighborSpan, ...], ...]
    junction_distance_from_start: np.ndarray  # float64 [L], along the lane graph to the next junction lane
    is_ending: np.ndarray  # bool [L], a lane that ends beside a neighbour that goes on (see `_ending_lanes`)

    @classmethod
    def build(cls, road_map: RoadMap, infer_neighbors: bool = False, infer_links: bool = True) -> MapIndex:
        """Index `road_map`; with `infer_neighbors`, a map without neighbour lists gets them from geometry; with
        `infer_links` (the default), a map that links no lanes gets its exits and entries from geometry
        (`lane_graph._geometric_links`)."""
        lane_feats = road_map.lanes
        index = {f.id: i for i, f in enumerate(lane_feats)}
        lanes = SegmentSet.build([f.points for f in lane_feats])
        lengths = np.array([arc_lengths(f.points)[-1] if len(f.points) > 1 else 0.0 for f in lane_feats])
        exits = tuple(tuple(index[e] for e in f.exit_lanes if e in index) for f in lane_feats)
        entries = tuple(tuple(index[e] for e in f.entry_lanes if e in index) for f in lane_feats)
        connectivity_source = "map" if any(exits) or any(entries) else "none"
        if infer_links and connectivity_source == "none" and lane_feats:  # a map that links no lanes: by geometry
            exits, entries = _geometric_links(lane_feats), tuple(() for _ in lane_feats)
            connectivity_source = "geometry" if any(exits) else "none"
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
            connectivity_source=connectivity_source,
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
        """Position of `lane` among its same-direction neighbours at `station` (`lanes_beside` on each side):
        "unknown" where the map has no neighbour information (and none is inferred) or the lane is a junction
        lane."""
        if self.neighbor_source == "none" or self.is_junction[lane]:
            return "unknown"
        has_left = bool(self.lanes_beside(lane, station, "left", with_ending))
        has_right = bool(self.lanes_beside(lane, station, "right", with_ending))
        if has_left and has_right:
            return "middle"
        if has_left:
            return "rightmost"
        return "leftmost" if has_right else "single"

    def lanes_beside(self, lane: int, station: float, side: Side, with_ending: bool = False) -> tuple[int, ...]:
        """The lanes beside `lane` on `side` at `station`, nearest first: the one definition of a neighbour lane,
        read by `lane_position` (both labelers), the counterfactual feasibility and the lane-change target.

        With map neighbour lists, the listed lanes whose span covers `station`; with inferred neighbours, the
        same-direction lanes whose centreline runs 2.5-4.5 m to that side there; none without neighbour
        information or on a junction lane. Only lanes of the same kind count: a bike lane beside the rightmost car
        lane is no neighbour; nor is a lane that ends beside it (an acceleration lane, a lane drop: `is_ending`),
        unless this lane ends too or `with_ending` (a change into or out of such a lane is placed among all the
        lanes there)."""
        if self.neighbor_source == "none" or self.is_junction[lane]:
            return ()
        if self.neighbor_source == "map":
            spans = self.left_spans[lane] if side == "left" else self.right_spans[lane]
            found = {s.lane for s in spans if self._counts_beside(lane, s.lane, with_ending) and _covers((s,), station)}
            if len(found) < 2:
                return tuple(found)
            point = self.point_at(lane, station)
            return tuple(sorted(found, key=lambda x: abs(float(self.project_to_lane(x, point)[1][0]))))
        return self._geometric_beside(lane, station, side, with_ending)

    def neighbour_lane(
        self, lane: int, station: float, side: Side, with_ending: bool = False
    ) -> tuple[int, float] | None:
        """The nearest lane beside `lane` on `side` at `station` (`lanes_beside`) and the station on it level
        with that point; None where there is none."""
        beside = self.lanes_beside(lane, station, side, with_ending)
        if not beside:
            return None
        stations, _ = self.project_to_lane(beside[0], self.point_at(lane, station))
        return beside[0], float(stations[0])

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

    def _geometric_beside(self, lane: int, station: float, side: Side, with_ending: bool) -> tuple[int, ...]:
        """The same-direction lanes 2.5-4.5 m to `side` of `lane` at `station`, nearest first."""
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
        # The point lies right of a lane on its left, so that lane's lateral offset of the point is negative.
        wanted = lateral < 0 if side == "left" else lateral > 0
        keep = same & apart & wanted
        order = np.argsort(np.abs(lateral[keep]), kind="stable")
        return tuple(dict.fromkeys(int(x) for x in self.lanes.owner[seg[keep]][order]))

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
