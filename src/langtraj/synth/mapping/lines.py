"""Road lines (lane dividers, double yellow centre lines) and road edges (the boundary of the
drivable area) of a SUMO net. See docs/data.md.
"""

from __future__ import annotations

import itertools
from collections import defaultdict
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import shapely
import sumolib
from shapely.geometry import LineString, MultiPolygon, Polygon
from shapely.geometry.polygon import orient

from langtraj.scenario.types import MapFeatureType
from langtraj.synth.mapping.common import (
    _MIN_STEP_M,
    CENTRE_LINE_MATCH_M,
    CLOSE_GAP_M,
    MAX_EDGE_PIECE_M,
    MEDIAN_MAX_HALF_WIDTH_M,
    MIN_AREA_M2,
    SIMPLIFY_M,
)
from langtraj.synth.mapping.geometry import _split_ring, densify, offset_polyline
from langtraj.synth.mapping.network import _Lane

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
