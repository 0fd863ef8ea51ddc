"""SUMO network -> LangTraj map model (WOMD's map): lanes, road lines, road edges, crosswalks, stop signs.

`build_net_map` reads a `.net.xml` once per simulated network; `crop_road_map` cuts the map of one
window out of it. Coordinates are SUMO net coordinates (x east, y north, metres); z is 0 unless the
net has elevation (lanes only; road edges, road lines and crosswalks are flat).

Conventions (WOMD-like):
- Every polyline is resampled so consecutive points are at most `point_spacing` apart (WOMD samples
  its map at about 0.5 m), so a window crop by "any point inside" keeps every feature that crosses it.
- Lanes: every lane a road vehicle or bicycle may use, junction-internal lanes included; those inside
  intersections (not merges, splits or mid-block crossings) are `interpolating`, as in WOMD; sidewalks,
  crossings and walking areas are not lanes.
- Road edges are the boundary of the drivable area (the union of all lane surfaces and the junction
  areas less their walking areas). Every ring runs with the drivable area on its LEFT (WOSAC's
  convention: port side on-road): outer rings counter-clockwise (ROAD_EDGE_BOUNDARY), holes clockwise
  (ROAD_EDGE_MEDIAN when narrow: medians, traffic and roundabout islands; ROAD_EDGE_BOUNDARY when wide:
  city blocks, see `MEDIAN_MAX_HALF_WIDTH_M`). A ring up to `MAX_EDGE_PIECE_M` long is one closed
  polyline (first point == last point); a longer one is split into pieces that share their end points.
- Lane boundaries point at road lines with their own type, and at road edges with type
  ROAD_LINE_UNKNOWN (as in WOMD, whose boundary segments carry a road-line type only).

See docs/data.md.
"""

from __future__ import annotations

import itertools
import math
import weakref
import xml.etree.ElementTree as ET
from collections import defaultdict
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import shapely
import sumolib
from shapely.geometry import LineString, MultiPolygon, Polygon
from shapely.geometry.polygon import orient

from langtraj.scenario.model import MPH_TO_MPS, BoundarySegment, LaneNeighbor, MapFeature, RoadMap
from langtraj.scenario.types import MapFeatureType

DRIVABLE_CLASSES = frozenset(
    {
        "passenger", "private", "taxi", "bus", "coach", "delivery", "truck", "trailer", "motorcycle",
        "moped", "evehicle", "emergency", "authority", "army", "vip", "hov", "custom1", "custom2", "bicycle",
    }
)  # fmt: skip
"""SUMO vehicle classes whose lanes become LANE_* features (road vehicles and bicycles)."""

FREEWAY_SPEED_MPS = 22.0
"""Lanes faster than this (about 80 km/h) are LANE_FREEWAY."""

FREEWAY_EDGE_TYPES = frozenset({"highway", "freeway", "motorway"})
FREEWAY_EDGE_TYPE_PREFIXES = ("highway.motorway", "highway.trunk")
"""Edge types (exact names, or OSM type prefixes: motorway, motorway_link, trunk, ...) whose lanes are
LANE_FREEWAY whatever their speed."""

POINT_SPACING_M = 0.5
"""Default largest distance between consecutive polyline points (WOMD's map sampling)."""

CLOSE_GAP_M = 0.1
"""Buffer out then in by this much to close hairline gaps between touching lane surfaces."""

SIMPLIFY_M = 0.1
"""Tolerance of the road edge simplification."""

MAX_EDGE_PIECE_M = 200.0
"""Road edge rings longer than this are split into pieces of about equal length."""

MIN_AREA_M2 = 0.5
"""Drivable patches and holes smaller than this are dropped (slivers)."""

MEDIAN_MAX_HALF_WIDTH_M = 15.0
"""Holes of the drivable area with 2 * area / perimeter (a strip's width, a disc's radius) up to this are
ROAD_EDGE_MEDIAN (medians, traffic and roundabout islands); wider holes (city blocks) ROAD_EDGE_BOUNDARY."""

BOUNDARY_MATCH_M = 0.5
"""A lane border point is bounded by a road edge that passes within this distance."""

CENTRE_LINE_MATCH_M = 0.5
"""Opposite edges whose left borders are this close share one double yellow centre line."""

STOP_SIGN_OFFSET_M = 2.0
"""Stop signs stand this far right of the end of the rightmost lane's centreline."""

_MIN_STEP_M = 1e-6


@dataclass(frozen=True)
class SignalLink:
    """One SUMO traffic-light link: the lane it controls and where vehicles stop for it."""

    tls_id: str
    link_index: int
    lane_id: int  # feature id of the connection's via (junction-internal) lane, or of the incoming lane without one
    stop_point: tuple[float, float, float]  # end of the incoming lane's centreline
    direction: str  # SUMO connection direction: s, l, r, t, L, R
    incoming_lane_id: int = -1  # feature id of the incoming (normal) lane


@dataclass(frozen=True, eq=False)
class NetMap:
    """The map of one SUMO network and the lookups from SUMO ids to map feature ids.

    `drivable_area` is the area whose boundary the road edges are (handy for off-road checks).
    """

    road_map: RoadMap
    lane_ids: Mapping[str, int]  # SUMO lane id (internal ':...' lanes too) -> lane feature id
    crossing_ids: Mapping[str, int]  # SUMO crossing edge id (':J_c0') -> CROSSWALK feature id
    signals: tuple[SignalLink, ...]  # sorted by (tls_id, link_index)
    junction_of_lane: Mapping[str, str]  # internal / crossing / walking area lane id -> junction id
    walkingareas: frozenset[str] = frozenset()  # SUMO walking-area edge ids
    drivable_area: Polygon | MultiPolygon = field(default_factory=Polygon)
    link_direction: Mapping[str, str] = field(default_factory=dict)  # via lane id -> SUMO direction (s, l, r, t, L, R)
    junction_control: Mapping[str, str] = field(default_factory=dict)  # junction id -> SUMO type (priority, ...)
    junction_legs: Mapping[str, int] = field(default_factory=dict)  # junction id -> number of roads meeting there
    intersections: frozenset[str] = frozenset()  # junctions that are intersections (`is_intersection`)
    roundabout_junctions: frozenset[str] = frozenset()  # junctions on a roundabout ring
    ending_lanes: frozenset[str] = frozenset()  # vehicle lanes with no onward connection where the road goes on


# ---------------------------------------------------------------------------------------------- geometry


def _dedupe(points: np.ndarray) -> np.ndarray:
    """Points without consecutive duplicates."""
    if len(points) < 2:
        return points
    step = np.linalg.norm(np.diff(points[:, :2], axis=0), axis=1)
    return points[np.concatenate([[True], step > _MIN_STEP_M])]


def densify(points: np.ndarray, spacing: float | None) -> np.ndarray:
    """The polyline with points inserted evenly so that no segment is longer than `spacing` (None: as is)."""
    if spacing is None or len(points) < 2:
        return points
    seg = np.diff(points, axis=0)
    length = np.linalg.norm(seg[:, :2], axis=1)
    parts = np.maximum(1, np.ceil(length / spacing - 1e-9)).astype(np.int64)
    start = np.repeat(points[:-1], parts, axis=0)
    frac = np.arange(parts.sum()) - np.repeat(np.cumsum(parts) - parts, parts)
    frac = (frac / np.repeat(parts, parts))[:, None]
    return np.concatenate([start + frac * np.repeat(seg, parts, axis=0), points[-1:]])


def offset_polyline(points: np.ndarray, distance: float) -> np.ndarray:
    """The polyline moved `distance` to its left (negative: right), with mitred vertices; same point count."""
    xy = points[:, :2]
    seg = np.diff(xy, axis=0)
    tangent = seg / np.maximum(np.linalg.norm(seg, axis=1, keepdims=True), _MIN_STEP_M)
    normal = np.stack([-tangent[:, 1], tangent[:, 0]], axis=1)
    before = np.concatenate([normal[:1], normal])
    after = np.concatenate([normal, normal[-1:]])
    cos_full = np.maximum(np.sum(before * after, axis=1, keepdims=True), -0.8)
    mitre = (before + after) / (1.0 + cos_full)
    out = points.copy()
    out[:, :2] = xy + distance * mitre
    return out


def _right_normal_at_end(points: np.ndarray) -> np.ndarray:
    d = points[-1, :2] - points[-2, :2]
    d = d / max(float(np.linalg.norm(d)), _MIN_STEP_M)
    return np.array([d[1], -d[0]])


def _split_ring(ring: np.ndarray, max_length: float) -> list[np.ndarray]:
    """A closed ring as consecutive pieces no longer than about `max_length`, sharing end points."""
    cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(ring[:, :2], axis=0), axis=1))])
    pieces = max(1, math.ceil(cum[-1] / max_length))
    if pieces == 1 or len(ring) < 2 * pieces + 1:
        return [ring]
    cuts = np.searchsorted(cum, cum[-1] * np.arange(1, pieces) / pieces)
    bounds = np.unique(np.concatenate([[0], np.clip(cuts, 1, len(ring) - 2), [len(ring) - 1]]))
    return [ring[a : b + 1] for a, b in itertools.pairwise(bounds)]


# ---------------------------------------------------------------------------------------------- reading the net


@dataclass(frozen=True, eq=False)
class _Lane:
    """One drivable SUMO lane as the mapping needs it."""

    sumo_id: str
    edge_id: str
    index: int
    internal: bool
    intersection: bool  # an internal lane of an intersection (see `is_intersection`)
    width: float
    speed: float
    bike_only: bool
    freeway_edge: bool
    points: np.ndarray  # densified centreline [N, 3]


def _is_drivable(lane: sumolib.net.lane.Lane) -> bool:
    return bool(DRIVABLE_CLASSES & set(lane.getPermissions()))


def _is_bike_only(lane: sumolib.net.lane.Lane) -> bool:
    return DRIVABLE_CLASSES & set(lane.getPermissions()) == {"bicycle"}


def _is_freeway_type(edge_type: str) -> bool:
    return edge_type in FREEWAY_EDGE_TYPES or edge_type.startswith(FREEWAY_EDGE_TYPE_PREFIXES)


def _read_lanes(net: sumolib.net.Net, spacing: float | None) -> dict[str, _Lane]:
    """Drivable lanes (normal and junction-internal) by SUMO id, in sorted id order."""
    lanes: dict[str, _Lane] = {}
    for edge in net.getEdges(withInternal=True):
        function = edge.getFunction()
        if function not in ("", "internal"):
            continue
        for lane in edge.getLanes():
            points = _dedupe(np.asarray(lane.getShape3D(), np.float64).reshape(-1, 3))
            if not _is_drivable(lane) or len(points) < 2:
                continue
            lanes[lane.getID()] = _Lane(
                sumo_id=lane.getID(),
                edge_id=edge.getID(),
                index=lane.getIndex(),
                internal=function == "internal",
                intersection=function == "internal" and is_intersection(edge.getFromNode()),
                width=float(lane.getWidth()),
                speed=float(lane.getSpeed()),
                bike_only=_is_bike_only(lane),
                freeway_edge=_is_freeway_type(edge.getType()),
                points=densify(points, spacing),
            )
    return {k: lanes[k] for k in sorted(lanes)}


def _change_permissions(net_file: Path) -> dict[str, tuple[bool, bool]]:
    """(may change left, may change right) for passenger cars, per lane with changeLeft/changeRight in the net."""
    raw = net_file.read_bytes()
    if b"changeLeft" not in raw and b"changeRight" not in raw:
        return {}
    result: dict[str, tuple[bool, bool]] = {}
    for _, elem in ET.iterparse(net_file, events=("end",)):
        if elem.tag == "lane" and ("changeLeft" in elem.attrib or "changeRight" in elem.attrib):
            result[elem.attrib["id"]] = (
                _allows_cars(elem.attrib.get("changeLeft")),
                _allows_cars(elem.attrib.get("changeRight")),
            )
        elif elem.tag in ("edge", "junction"):
            elem.clear()
    return result


def _allows_cars(classes: str | None) -> bool:
    if classes is None:
        return True
    names = set(classes.split())
    return bool(names & {"all", "passenger"})


# ---------------------------------------------------------------------------------------------- connectivity


@dataclass(frozen=True)
class _Topology:
    exits: Mapping[str, tuple[str, ...]]
    entries: Mapping[str, tuple[str, ...]]
    source: Mapping[str, str]  # internal lane -> the normal lane that feeds it


def _topology(net: sumolib.net.Net, lanes: Mapping[str, _Lane]) -> _Topology:
    """Lane successors (the via lane of a connection, else its target lane) and their inverse."""
    exits: dict[str, set[str]] = defaultdict(set)
    feeds: dict[str, str] = {}
    for lane_id in lanes:
        for conn in net.getLane(lane_id).getOutgoing():
            nxt = conn.getViaLaneID() or conn.getToLane().getID()
            if nxt in lanes:
                exits[lane_id].add(nxt)
                if lanes[nxt].internal:
                    feeds[nxt] = lane_id
    entries: dict[str, set[str]] = defaultdict(set)
    for lane_id, nexts in exits.items():
        for nxt in nexts:
            entries[nxt].add(lane_id)
    source = {k: _resolve_source(k, feeds, lanes) for k in feeds}
    return _Topology(
        exits={k: tuple(sorted(v)) for k, v in exits.items()},
        entries={k: tuple(sorted(v)) for k, v in entries.items()},
        source=source,
    )


def _resolve_source(lane_id: str, feeds: Mapping[str, str], lanes: Mapping[str, _Lane]) -> str:
    seen = {lane_id}
    while lanes[lane_id].internal and lane_id in feeds and feeds[lane_id] not in seen:
        lane_id = feeds[lane_id]
        seen.add(lane_id)
    return lane_id


def _lane_type(lane: _Lane, lanes: Mapping[str, _Lane], topo: _Topology) -> MapFeatureType:
    if lane.bike_only:
        return MapFeatureType.LANE_BIKE_LANE
    ref = lanes[topo.source.get(lane.sumo_id, lane.sumo_id)]
    if ref.freeway_edge or ref.speed > FREEWAY_SPEED_MPS:
        return MapFeatureType.LANE_FREEWAY
    return MapFeatureType.LANE_SURFACE_STREET


# ---------------------------------------------------------------------------------------------- road lines


@dataclass(frozen=True, eq=False)
class _Line:
    """A road line and the lane sides it bounds: (SUMO lane id, 'left' | 'right')."""

    type: MapFeatureType
    points: np.ndarray
    bounds: tuple[tuple[str, str], ...]


def _edge_lanes(lanes: Mapping[str, _Lane]) -> dict[str, list[_Lane]]:
    """Drivable lanes of each normal edge, rightmost first."""
    by_edge: dict[str, list[_Lane]] = defaultdict(list)
    for lane in lanes.values():
        if not lane.internal:
            by_edge[lane.edge_id].append(lane)
    return {e: sorted(v, key=lambda ln: ln.index) for e, v in sorted(by_edge.items())}


def _divider_lines(edge_lanes: Mapping[str, list[_Lane]], change: Mapping[str, tuple[bool, bool]]) -> list[_Line]:
    """White lines between adjacent same-direction lanes: solid where changing is forbidden or by a bike lane."""
    lines = []
    for group in edge_lanes.values():
        for right, left in itertools.pairwise(group):
            if left.index != right.index + 1:
                continue
            may_change = change.get(right.sumo_id, (True, True))[0] and change.get(left.sumo_id, (True, True))[1]
            solid = right.bike_only or left.bike_only or not may_change
            kind = (
                MapFeatureType.ROAD_LINE_SOLID_SINGLE_WHITE if solid else MapFeatureType.ROAD_LINE_BROKEN_SINGLE_WHITE
            )
            points = offset_polyline(right.points, right.width / 2.0)
            lines.append(_Line(kind, points, ((right.sumo_id, "left"), (left.sumo_id, "right"))))
    return lines


def _centre_lines(net: sumolib.net.Net, edge_lanes: Mapping[str, list[_Lane]]) -> list[_Line]:
    """One double yellow line per pair of adjacent opposite-direction edges, on the left border of both."""
    lines = []
    for edge_id, group in edge_lanes.items():
        edge = net.getEdge(edge_id)
        for other in edge.getToNode().getOutgoing():
            other_id = other.getID()
            if other.getToNode() != edge.getFromNode() or other_id not in edge_lanes or other_id <= edge_id:
                continue
            mine, theirs = group[-1], edge_lanes[other_id][-1]
            border = offset_polyline(mine.points, mine.width / 2.0)
            their_border = LineString(offset_polyline(theirs.points, theirs.width / 2.0)[:, :2])
            gap = shapely.distance(shapely.points(border[:, :2]), their_border)
            if float(np.mean(gap)) <= CENTRE_LINE_MATCH_M:
                bounds = ((mine.sumo_id, "left"), (theirs.sumo_id, "left"))
                lines.append(_Line(MapFeatureType.ROAD_LINE_SOLID_DOUBLE_YELLOW, border, bounds))
    return lines


# ---------------------------------------------------------------------------------------------- road edges


def _linestrings(polylines: Sequence[np.ndarray]) -> np.ndarray:
    """Shapely LineStrings of [N, 2+] polylines, in one vectorized call."""
    counts = [len(p) for p in polylines]
    return shapely.linestrings(
        np.concatenate([p[:, :2] for p in polylines]), indices=np.repeat(np.arange(len(counts)), counts)
    )


def _lane_surfaces(lanes: Iterable[_Lane]) -> list[Polygon]:
    items = list(lanes)
    lines = _linestrings([ln.points for ln in items])
    widths = np.array([ln.width / 2.0 for ln in items])
    return list(shapely.buffer(lines, widths, cap_style="flat", join_style="round", quad_segs=4))


def _junction_areas(net: sumolib.net.Net, lanes: Mapping[str, _Lane]) -> list[Polygon]:
    """Junction shapes less their walking areas, for junctions that drivable lanes touch."""
    touched = {net.getEdge(ln.edge_id).getFromNode().getID() for ln in lanes.values()}
    touched |= {net.getEdge(ln.edge_id).getToNode().getID() for ln in lanes.values()}
    walking: dict[str, list[Polygon]] = defaultdict(list)
    for edge in net.getEdges(withInternal=True):
        if edge.getFunction() == "walkingarea":
            for lane in edge.getLanes():
                if len(lane.getShape()) >= 3:
                    walking[edge.getFromNode().getID()].append(Polygon(lane.getShape()).buffer(0))
    areas = []
    for node in net.getNodes():
        shape = node.getShape()
        if node.getID() not in touched or len(shape) < 3:
            continue
        area = Polygon(shape).buffer(0)
        if walking.get(node.getID()):
            area = area.difference(shapely.union_all(walking[node.getID()]))
        if not area.is_empty:
            areas.append(area)
    return areas


def _drivable_area(net: sumolib.net.Net, lanes: Mapping[str, _Lane]) -> Polygon | MultiPolygon:
    """Union of lane surfaces and junction areas, hairline gaps closed, simplified, slivers dropped."""
    if not lanes:
        return Polygon()
    union = shapely.union_all(_lane_surfaces(lanes.values()) + _junction_areas(net, lanes))
    closed = union.buffer(CLOSE_GAP_M, join_style="mitre").buffer(-CLOSE_GAP_M, join_style="mitre")
    simple = closed.simplify(SIMPLIFY_M, preserve_topology=True)
    polygons = []
    for poly in getattr(simple, "geoms", [simple]):
        if isinstance(poly, Polygon) and poly.area >= MIN_AREA_M2:
            holes = [h for h in poly.interiors if Polygon(h).area >= MIN_AREA_M2]
            polygons.append(orient(Polygon(poly.exterior, holes), sign=1.0))
    polygons.sort(key=lambda p: (round(p.bounds[0], 3), round(p.bounds[1], 3)))
    return polygons[0] if len(polygons) == 1 else MultiPolygon(polygons)


def _hole_type(hole: shapely.LinearRing) -> MapFeatureType:
    """A narrow hole (median, traffic or roundabout island) is a median; a wide one (a city block) a boundary."""
    half_width = 2.0 * Polygon(hole).area / max(hole.length, _MIN_STEP_M)
    return (
        MapFeatureType.ROAD_EDGE_MEDIAN if half_width <= MEDIAN_MAX_HALF_WIDTH_M else MapFeatureType.ROAD_EDGE_BOUNDARY
    )


def _edge_rings(area: Polygon | MultiPolygon, spacing: float | None) -> list[tuple[MapFeatureType, np.ndarray]]:
    """Road edge polylines of the drivable area: outer rings CCW, holes CW (drivable on the left)."""
    result = []
    for poly in getattr(area, "geoms", [area]):
        if poly.is_empty:
            continue
        rings = [(MapFeatureType.ROAD_EDGE_BOUNDARY, poly.exterior)]
        rings += [(_hole_type(hole), hole) for hole in poly.interiors]
        for kind, ring in rings:
            xyz = np.zeros((len(ring.coords), 3))
            xyz[:, :2] = np.asarray(ring.coords)[:, :2]
            for piece in _split_ring(densify(xyz, spacing), MAX_EDGE_PIECE_M):
                result.append((kind, piece))
    return result


# ---------------------------------------------------------------------------------------------- assembling


class _Ids:
    """Sequential feature ids per category."""

    def __init__(self) -> None:
        self.next = 0

    def take(self, count: int) -> list[int]:
        ids = list(range(self.next, self.next + count))
        self.next += count
        return ids


def _line_boundaries(
    lines: Sequence[_Line], line_ids: Sequence[int], lanes: Mapping[str, _Lane]
) -> dict[tuple[str, str], list[BoundarySegment]]:
    """(lane, side) -> boundary segments over the whole lane, for road lines."""
    result: dict[tuple[str, str], list[BoundarySegment]] = defaultdict(list)
    for line, fid in zip(lines, line_ids, strict=True):
        for lane_id, side in line.bounds:
            last = len(lanes[lane_id].points) - 1
            result[(lane_id, side)].append(BoundarySegment(0, last, fid, line.type))
    return result


def _nearest_edge(points: np.ndarray, edges: Sequence[np.ndarray], edge_ids: Sequence[int]) -> np.ndarray:
    """Per point [P, 2]: the id of the nearest road edge within `BOUNDARY_MATCH_M`, else -1."""
    pieces = np.concatenate([np.stack([e[:-1, :2], e[1:, :2]], axis=1) for e in edges])
    piece_owner = np.repeat(np.asarray(edge_ids, np.int64), [len(e) - 1 for e in edges])
    tree = shapely.STRtree(shapely.linestrings(pieces))
    hit_point, hit_piece = tree.query_nearest(shapely.points(points), max_distance=BOUNDARY_MATCH_M, all_matches=False)
    owner = np.full(len(points), -1, np.int64)
    owner[hit_point] = piece_owner[hit_piece]
    return owner


def _edge_boundaries(
    lanes: Mapping[str, _Lane], taken: set[tuple[str, str]], edges: Sequence[np.ndarray], edge_ids: Sequence[int]
) -> dict[tuple[str, str], list[BoundarySegment]]:
    """(lane, side) -> segments bounded by a road edge, for the outer sides of normal lanes (no road line there)."""
    sides = [
        (lane, side)
        for lane in lanes.values()
        if not lane.internal
        for side in ("left", "right")
        if (lane.sumo_id, side) not in taken
    ]
    if not sides or not edges:
        return {}
    borders = [offset_polyline(ln.points, (1 if s == "left" else -1) * ln.width / 2.0)[:, :2] for ln, s in sides]
    owner = _nearest_edge(np.concatenate(borders), edges, edge_ids)
    chunks = np.split(owner, np.cumsum([len(b) for b in borders])[:-1])
    result = {(lane.sumo_id, side): _runs(chunk) for (lane, side), chunk in zip(sides, chunks, strict=True)}
    return {k: v for k, v in result.items() if v}


def _runs(owner: np.ndarray) -> list[BoundarySegment]:
    """Runs of equal, non-negative feature ids (two points or more) as boundary segments."""
    change = np.flatnonzero(np.diff(owner)) + 1
    starts = np.concatenate([[0], change])
    ends = np.concatenate([change - 1, [len(owner) - 1]])
    return [
        BoundarySegment(int(a), int(b), int(owner[a]), MapFeatureType.ROAD_LINE_UNKNOWN)
        for a, b in zip(starts, ends, strict=True)
        if owner[a] >= 0 and b > a
    ]


def _neighbors(
    lane: _Lane,
    lanes: Mapping[str, _Lane],
    ids: Mapping[str, int],
    bounds: Mapping[tuple[str, str], list[BoundarySegment]],
) -> tuple[tuple[LaneNeighbor, ...], tuple[LaneNeighbor, ...]]:
    """Left and right neighbours: the adjacent-index drivable lanes of the same edge, over whole polylines."""
    prefix = lane.sumo_id[: lane.sumo_id.rfind("_") + 1]
    out = []
    for side, index in (("left", lane.index + 1), ("right", lane.index - 1)):
        other = lanes.get(f"{prefix}{index}")
        if other is None or other.edge_id != lane.edge_id:
            out.append(())
            continue
        segs = tuple(
            s for s in bounds.get((lane.sumo_id, side), ()) if s.boundary_type != MapFeatureType.ROAD_LINE_UNKNOWN
        )
        n_self, n_other = len(lane.points) - 1, len(other.points) - 1
        out.append((LaneNeighbor(ids[other.sumo_id], 0, n_self, 0, n_other, segs),))
    return out[0], out[1]


def _lane_features(
    lanes: Mapping[str, _Lane],
    ids: Mapping[str, int],
    topo: _Topology,
    bounds: Mapping[tuple[str, str], list[BoundarySegment]],
) -> list[MapFeature]:
    features = []
    for lane_id, lane in lanes.items():
        left, right = _neighbors(lane, lanes, ids, bounds)
        features.append(
            MapFeature(
                ids[lane_id],
                _lane_type(lane, lanes, topo),
                lane.points,
                entry_lanes=tuple(sorted(ids[k] for k in topo.entries.get(lane_id, ()))),
                exit_lanes=tuple(sorted(ids[k] for k in topo.exits.get(lane_id, ()))),
                left_neighbors=left,
                right_neighbors=right,
                left_boundaries=tuple(bounds.get((lane_id, "left"), ())),
                right_boundaries=tuple(bounds.get((lane_id, "right"), ())),
                speed_limit_mph=lane.speed / MPH_TO_MPS,
                interpolating=lane.intersection,
            )
        )
    return features


def _crosswalks(net: sumolib.net.Net) -> dict[str, np.ndarray]:
    """Crossing edge id -> crosswalk polygon (4+ corners, CCW, not closed)."""
    result = {}
    for edge in net.getEdges(withInternal=True):
        if edge.getFunction() != "crossing":
            continue
        lane = edge.getLanes()[0]
        shape = _dedupe(np.asarray(lane.getShape(), np.float64))
        if len(shape) < 2:
            continue
        poly = orient(LineString(shape).buffer(lane.getWidth() / 2.0, cap_style="flat", join_style="mitre"), 1.0)
        corners = np.asarray(poly.exterior.coords)[:-1, :2]
        result[edge.getID()] = np.concatenate([corners, np.zeros((len(corners), 1))], axis=1)
    return dict(sorted(result.items()))


def _stop_controlled(net: sumolib.net.Net, lanes: Mapping[str, _Lane]) -> dict[tuple[str, str], list[str]]:
    """(junction id, incoming edge id) -> the edge's lanes with a stop ('s') or all-way stop ('w') link."""
    result: dict[tuple[str, str], set[str]] = defaultdict(set)
    for lane_id, lane in lanes.items():
        if lane.internal:
            continue
        for conn in net.getLane(lane_id).getOutgoing():
            if conn.getState() in ("s", "w"):
                junction = net.getEdge(lane.edge_id).getToNode().getID()
                result[(junction, lane.edge_id)].add(lane_id)
    return {k: sorted(v) for k, v in sorted(result.items())}


def _stop_sign(edge_lanes: Sequence[_Lane], controlled: Sequence[str], ids: Mapping[str, int], fid: int) -> MapFeature:
    """A stop sign right of the end of the incoming edge's rightmost drivable lane (`edge_lanes[0]`)."""
    rightmost = edge_lanes[0]
    end = rightmost.points[-1].copy()
    end[:2] += STOP_SIGN_OFFSET_M * _right_normal_at_end(rightmost.points)
    return MapFeature(
        fid, MapFeatureType.STOP_SIGN, end[None], controlled_lanes=tuple(sorted(ids[k] for k in controlled))
    )


def _signals(net: sumolib.net.Net, lanes: Mapping[str, _Lane], ids: Mapping[str, int]) -> tuple[SignalLink, ...]:
    """Traffic-light links of vehicle and bicycle connections, sorted by (tls id, link index)."""
    links = []
    for lane_id, lane in lanes.items():
        if lane.internal:
            continue
        for conn in net.getLane(lane_id).getOutgoing():
            if not conn.getTLSID() or conn.getTLLinkIndex() < 0:
                continue
            controlled = ids.get(conn.getViaLaneID() or "", ids[lane_id])
            stop = tuple(float(v) for v in lane.points[-1])
            links.append(
                SignalLink(conn.getTLSID(), conn.getTLLinkIndex(), controlled, stop, conn.getDirection(), ids[lane_id])
            )
    return tuple(sorted(links, key=lambda s: (s.tls_id, s.link_index, s.lane_id)))


def _junction_of_lanes(net: sumolib.net.Net) -> dict[str, str]:
    return {
        lane.getID(): edge.getFromNode().getID()
        for edge in net.getEdges(withInternal=True)
        if edge.getFunction() in ("internal", "crossing", "walkingarea")
        for lane in edge.getLanes()
    }


def _link_directions(net: sumolib.net.Net) -> dict[str, str]:
    """Junction-internal (via) lane -> direction of the connection that uses it."""
    return {
        conn.getViaLaneID(): conn.getDirection()
        for edge in net.getEdges(withInternal=False)
        for lane in edge.getLanes()
        for conn in lane.getOutgoing()
        if conn.getViaLaneID()
    }


def is_intersection(node: sumolib.net.node.Node) -> bool:
    """Roads from two or more places meet roads to two or more places, three roads at least: not a merge,
    a split or a mid-block crossing."""
    sources = {e.getFromNode().getID() for e in node.getIncoming() if not e.getFunction()}
    targets = {e.getToNode().getID() for e in node.getOutgoing() if not e.getFunction()}
    return len(sources) >= 2 and len(targets) >= 2 and _legs(node) >= 3


def _legs(node: sumolib.net.node.Node) -> int:
    """Roads meeting at a junction: its distinct neighbouring junctions (2 at a mid-block crossing)."""
    ends = {e.getFromNode().getID() for e in node.getIncoming() if not e.getFunction()}
    ends |= {e.getToNode().getID() for e in node.getOutgoing() if not e.getFunction()}
    return len(ends - {node.getID()})


def _ending_lanes(net: sumolib.net.Net) -> frozenset[str]:
    """Vehicle lanes without an onward connection on edges that do continue: acceleration lanes, lane drops."""
    return frozenset(
        lane.getID()
        for edge in net.getEdges(withInternal=False)
        if edge.getOutgoing()
        for lane in edge.getLanes()
        if lane.allows("passenger") and not lane.getOutgoing()
    )


def build_net_map(net_file: Path, *, point_spacing: float | None = POINT_SPACING_M) -> NetMap:
    """Read a SUMO `.net.xml` into LangTraj's map model with the SUMO-id lookups that windows and events need.

    Feature ids are sequential: lanes (sorted SUMO ids), road lines, road edges, crosswalks, stop signs.
    `point_spacing` resamples every polyline to at most that spacing (None keeps SUMO's points).
    """
    net_file = Path(net_file)
    net = sumolib.net.readNet(str(net_file), withInternal=True, withPedestrianConnections=True)
    lanes = _read_lanes(net, point_spacing)
    topo = _topology(net, lanes)
    ids = _Ids()
    lane_ids = dict(zip(lanes, ids.take(len(lanes)), strict=True))

    edge_lanes = _edge_lanes(lanes)
    lines = _divider_lines(edge_lanes, _change_permissions(net_file)) + _centre_lines(net, edge_lanes)
    line_ids = ids.take(len(lines))
    area = _drivable_area(net, lanes)
    rings = _edge_rings(area, point_spacing)
    ring_ids = ids.take(len(rings))
    crossings = _crosswalks(net)
    crossing_ids = dict(zip(crossings, ids.take(len(crossings)), strict=True))
    stops = _stop_controlled(net, lanes)
    stop_ids = ids.take(len(stops))

    bounds = _line_boundaries(lines, line_ids, lanes)
    bounds.update(_edge_boundaries(lanes, set(bounds), [r for _, r in rings], ring_ids))
    features = _lane_features(lanes, lane_ids, topo, bounds)
    features += [MapFeature(fid, ln.type, ln.points) for ln, fid in zip(lines, line_ids, strict=True)]
    features += [MapFeature(fid, kind, pts) for (kind, pts), fid in zip(rings, ring_ids, strict=True)]
    features += [MapFeature(crossing_ids[k], MapFeatureType.CROSSWALK, pts) for k, pts in crossings.items()]
    features += [
        _stop_sign(edge_lanes[edge_id], controlled, lane_ids, fid)
        for ((_, edge_id), controlled), fid in zip(stops.items(), stop_ids, strict=True)
    ]
    return NetMap(
        road_map=RoadMap(tuple(features)),
        lane_ids=lane_ids,
        crossing_ids=crossing_ids,
        signals=_signals(net, lanes, lane_ids),
        junction_of_lane=_junction_of_lanes(net),
        walkingareas=frozenset(e.getID() for e in net.getEdges(withInternal=True) if e.getFunction() == "walkingarea"),
        drivable_area=area,
        link_direction=_link_directions(net),
        junction_control={node.getID(): node.getType() for node in net.getNodes()},
        junction_legs={node.getID(): _legs(node) for node in net.getNodes()},
        intersections=frozenset(node.getID() for node in net.getNodes() if is_intersection(node)),
        roundabout_junctions=frozenset(n for r in net.getRoundabouts() for n in r.getNodes()),
        ending_lanes=_ending_lanes(net),
    )


# ---------------------------------------------------------------------------------------------- cropping


@dataclass(frozen=True, eq=False)
class _MapIndex:
    """All map points of a road map in one array, with the index of the feature each belongs to."""

    xy: np.ndarray  # float64 [P, 2]
    owner: np.ndarray  # int64 [P]
    refs: tuple[frozenset[int], ...]  # per feature: the feature ids it references


_INDEX_CACHE: weakref.WeakKeyDictionary[RoadMap, _MapIndex] = weakref.WeakKeyDictionary()


def _references(feature: MapFeature) -> frozenset[int]:
    ids = set(feature.entry_lanes) | set(feature.exit_lanes) | set(feature.controlled_lanes)
    for nb in (*feature.left_neighbors, *feature.right_neighbors):
        ids.add(nb.feature_id)
        ids.update(s.boundary_feature_id for s in nb.boundaries)
    ids.update(s.boundary_feature_id for s in (*feature.left_boundaries, *feature.right_boundaries))
    return frozenset(ids)


def _map_index(road_map: RoadMap) -> _MapIndex:
    index = _INDEX_CACHE.get(road_map)
    if index is None:
        features = road_map.features
        counts = np.array([len(f.points) for f in features], np.int64)
        xy = np.concatenate([f.points[:, :2] for f in features]) if len(features) else np.zeros((0, 2))
        owner = np.repeat(np.arange(len(features)), counts)
        index = _MapIndex(xy, owner, tuple(_references(f) for f in features))
        _INDEX_CACHE[road_map] = index
    return index


def _without(feature: MapFeature, kept: set[int]) -> MapFeature:
    """The feature with every reference to a feature outside `kept` removed."""

    def segs(items: Iterable[BoundarySegment]) -> tuple[BoundarySegment, ...]:
        return tuple(s for s in items if s.boundary_feature_id in kept)

    def nbs(items: Iterable[LaneNeighbor]) -> tuple[LaneNeighbor, ...]:
        return tuple(replace(n, boundaries=segs(n.boundaries)) for n in items if n.feature_id in kept)

    return replace(
        feature,
        entry_lanes=tuple(i for i in feature.entry_lanes if i in kept),
        exit_lanes=tuple(i for i in feature.exit_lanes if i in kept),
        controlled_lanes=tuple(i for i in feature.controlled_lanes if i in kept),
        left_neighbors=nbs(feature.left_neighbors),
        right_neighbors=nbs(feature.right_neighbors),
        left_boundaries=segs(feature.left_boundaries),
        right_boundaries=segs(feature.right_boundaries),
    )


def crop_road_map(road_map: RoadMap, xy_min: Sequence[float], xy_max: Sequence[float]) -> RoadMap:
    """The features with any point inside the box [xy_min, xy_max], references to dropped features removed.

    Cheap per call (the point index of `road_map` is built once and cached), so windows can crop freely.
    """
    index = _map_index(road_map)
    lo, hi = np.asarray(xy_min, np.float64)[:2], np.asarray(xy_max, np.float64)[:2]
    inside = np.all((index.xy >= lo) & (index.xy <= hi), axis=1)
    keep = np.unique(index.owner[inside])
    features = road_map.features
    kept = {features[i].id for i in keep.tolist()}
    out = []
    for i in keep.tolist():
        feature = features[i]
        out.append(feature if index.refs[i] <= kept else _without(feature, kept))
    return RoadMap(tuple(out))
