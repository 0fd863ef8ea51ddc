"""Assembling the map of a SUMO net: lane features with boundaries and neighbours, crosswalks, stop
signs, signal links, and `build_net_map`. See docs/data.md.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import shapely
import sumolib
from shapely.geometry import LineString
from shapely.geometry.polygon import orient

from langtraj.scenario.model import MPH_TO_MPS, BoundarySegment, LaneNeighbor, MapFeature, RoadMap
from langtraj.scenario.types import MapFeatureType
from langtraj.synth.mapping.common import BOUNDARY_MATCH_M, POINT_SPACING_M, STOP_SIGN_OFFSET_M, NetMap, SignalLink
from langtraj.synth.mapping.geometry import _dedupe, _right_normal_at_end, offset_polyline
from langtraj.synth.mapping.lines import _centre_lines, _divider_lines, _drivable_area, _edge_lanes, _edge_rings, _Line
from langtraj.synth.mapping.network import (
    _change_permissions,
    _Lane,
    _lane_type,
    _legs,
    _read_lanes,
    _Topology,
    _topology,
    is_intersection,
)

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
