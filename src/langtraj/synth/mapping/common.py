"""Constants of the SUMO net -> map conversion (vehicle classes, spacings, tolerances) and its result
types `NetMap` and `SignalLink`. See docs/data.md.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

from shapely.geometry import MultiPolygon, Polygon

from langtraj.scenario.model import RoadMap

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
