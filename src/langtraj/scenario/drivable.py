"""A drivable area for maps that have lanes but no road edges (nuScenes via ScenarioNet), as road-edge rings.

Off-road is measured (`metrics`), steered against (`guidance`) and judged (`env`) against road edges; a map without
any gave no measure at all and let simulated cars leave the mapped roads unnoticed. `measured_road_edges` is the one
place those three get a scenario's edges: the map's own where it has any (untouched, bit for bit), else rings derived
here from the union of the lanes' areas (and nuScenes's drivable-area outline where the file carries it), each
marked with `MapFeature.derived_from`. A map with neither edges nor lanes stays unmeasured. The switch
`LANGTRAJ_DERIVED_ROAD_EDGES=0` turns the derivation off everywhere at once.

See docs/data.md, 'Derived drivable area'.
"""

from __future__ import annotations

import os
import weakref
from collections.abc import Iterable, Sequence
from dataclasses import replace

import numpy as np
import shapely
from shapely.geometry import LineString, Point, Polygon
from shapely.geometry.polygon import orient

from langtraj.errors import InputError
from langtraj.scenario.model import MapFeature, RoadMap, Scenario
from langtraj.scenario.types import MapFeatureType

DEFAULT_LANE_WIDTH_M = 3.6
"""Width of a lane the file gives no outline for (its centre line is buffered by half of it): the common standard
lane width (12 ft), just above the 3.4 m median width measured at the centres of the 755 outlined lanes of the five
nuScenes mini scenes; the files record no width of their own."""
CLOSING_RADIUS_M = 0.25
"""The union is closed (grown, then shrunk) by this much, so cracks between adjacent lane outlines vanish."""
MIN_HOLE_AREA_M2 = 10.0
"""Holes smaller than this (about a car's footprint) are gaps between lane areas, not islands, and are filled."""
SIMPLIFY_TOLERANCE_M = 0.1
"""The rings are simplified to within this distance of the union's outline."""
SWITCH = "LANGTRAJ_DERIVED_ROAD_EDGES"
"""Environment variable: 0 (or false, no, off) turns the derivation off for every consumer; default on."""
FROM_LANES = "lanes"
FROM_LANES_AND_OUTLINE = "lanes and drivable-area outline"
"""`MapFeature.derived_from` of derived edges: from the lanes alone, or from them and the source's outline."""

_OUTLINE_KEY = "boundary_"  # ScenarioNet's nuScenes converter: the drivable area's outline rings, as road lines
_CLOSED_M = 1e-3
_cache: weakref.WeakKeyDictionary[RoadMap, tuple[MapFeature, ...]] = weakref.WeakKeyDictionary()


def derived_road_edges_enabled() -> bool:
    """Whether maps without road edges get derived ones (`SWITCH`; on unless set to 0, false, no or off)."""
    value = os.environ.get(SWITCH, "1").strip().lower()
    if value in ("", "1", "true", "yes", "on"):
        return True
    if value in ("0", "false", "no", "off"):
        return False
    raise InputError(f"must be 1 or 0, got {value!r}", where=SWITCH)


def measured_road_edges(scenario: Scenario, *, derive: bool | None = None) -> list[MapFeature]:
    """The road edges off-road is measured and steered against: the map's own where it has any, else (when `derive`,
    default the `SWITCH`) those `derive_road_edges` gives, computed once per road map."""
    own = scenario.road_map.road_edges
    if own or not (derived_road_edges_enabled() if derive is None else derive):
        return own
    road_map = scenario.road_map
    if road_map not in _cache:
        _cache[road_map] = derive_road_edges(road_map, outline_ids=drivable_outline_ids(scenario))
    return list(_cache[road_map])


def road_edges_derived_from(scenario: Scenario) -> str:
    """What the scenario's measured road edges were derived from (`FROM_LANES`, ...), "" when they are the map's own
    or there are none: what a page or report says beside an off-road figure."""
    edges = measured_road_edges(scenario)
    return edges[0].derived_from if edges else ""


def with_derived_road_edges(scenario: Scenario, **options: float) -> Scenario:
    """The scenario with derived road edges appended to its map (for drawing them, say); the same scenario when its
    map has road edges or nothing to derive them from. `options`: those of `derive_road_edges`."""
    if scenario.road_map.road_edges:
        return scenario
    edges = derive_road_edges(scenario.road_map, outline_ids=drivable_outline_ids(scenario), **options)
    if not edges:
        return scenario
    return replace(scenario, road_map=RoadMap(scenario.road_map.features + edges))


def drivable_outline_ids(scenario: Scenario) -> tuple[int, ...]:
    """Ids of the map's rings that outline the drivable area: ScenarioNet's nuScenes converter writes nuScenes's
    drivable-area polygons as closed white road lines keyed `boundary_N` (their keys are in
    `metadata["scenarionet"]["map_keys"]`); none for any other source."""
    sn = scenario.metadata.get("scenarionet")
    if not isinstance(sn, dict) or not isinstance(sn.get("source_metadata"), dict):
        return ()
    keys = sn.get("map_keys")
    features = scenario.road_map.features
    if sn["source_metadata"].get("dataset") != "nuscenes" or not isinstance(keys, list) or len(keys) != len(features):
        return ()
    return tuple(
        f.id
        for f, key in zip(features, keys, strict=True)
        if str(key).startswith(_OUTLINE_KEY) and f.type.is_road_line and _closed(f.points)
    )


def derive_road_edges(
    road_map: RoadMap,
    *,
    outline_ids: Sequence[int] = (),
    lane_width: float = DEFAULT_LANE_WIDTH_M,
    min_hole_area: float = MIN_HOLE_AREA_M2,
    tolerance: float = SIMPLIFY_TOLERANCE_M,
) -> tuple[MapFeature, ...]:
    """Closed ROAD_EDGE_BOUNDARY rings around the drivable area of a map with lanes and no road edges (none
    otherwise): the union of every lane's outline (its `polygon` where the file gives one, else its centre line
    buffered by `lane_width` / 2) and of the areas the `outline_ids` rings enclose (even-odd), closed by
    `CLOSING_RADIUS_M`, holes under `min_hole_area` m^2 filled, simplified to `tolerance` m. Outer rings run
    counter-clockwise and holes clockwise, so the road is on every edge's left (the WOMD convention); z is 0."""
    if not lane_width > 0 or not min_hole_area >= 0 or not tolerance >= 0:
        raise InputError(
            f"need lane_width > 0, min_hole_area >= 0, tolerance >= 0; got {lane_width}, {min_hole_area}, {tolerance}"
        )
    lanes = [f for f in road_map.lanes if len(f.points)]
    if road_map.road_edges or not lanes:
        return ()
    area = shapely.union_all([_lane_area(f, lane_width / 2) for f in lanes])
    outline = _enclosed([road_map.by_id[i] for i in outline_ids if i in road_map.by_id])
    if outline is not None:
        area = area.union(outline)
    area = area.buffer(CLOSING_RADIUS_M).buffer(-CLOSING_RADIUS_M)
    polygons = [_filled(p, min_hole_area) for p in _polygons(area)]
    area = shapely.simplify(shapely.union_all(polygons), tolerance, preserve_topology=True)
    source = FROM_LANES_AND_OUTLINE if outline is not None else FROM_LANES
    next_id = max(f.id for f in road_map.features) + 1
    edges = []
    for polygon in _polygons(area):
        polygon = orient(polygon, sign=1.0)  # exterior counter-clockwise, holes clockwise: the road on the left
        for ring in (polygon.exterior, *polygon.interiors):
            xy = np.asarray(ring.coords)[:, :2]
            points = np.concatenate([xy, np.zeros((len(xy), 1))], axis=1)
            edges.append(MapFeature(next_id, MapFeatureType.ROAD_EDGE_BOUNDARY, points, derived_from=source))
            next_id += 1
    return tuple(edges)


def _lane_area(feature: MapFeature, half_width: float):
    """A lane's outline where the file gives a usable one, else its centre line buffered by `half_width`."""
    if feature.polygon is not None and len(feature.polygon) >= 3:
        outline = shapely.make_valid(Polygon(feature.polygon[:, :2]))
        if outline.area > 0:
            return shapely.union_all(_polygons(outline))
    xy = feature.points[:, :2]
    centre = LineString(xy) if len(xy) >= 2 else Point(xy[0])
    return centre.buffer(half_width)


def _enclosed(rings: Iterable[MapFeature]):
    """The area closed rings enclose, by the even-odd rule (a ring inside another cuts a hole), or None."""
    area = None
    for ring in rings:
        if len(ring.points) < 4:
            continue
        part = shapely.union_all(_polygons(shapely.make_valid(Polygon(ring.points[:, :2]))))
        area = part if area is None else area.symmetric_difference(part)
    return area


def _polygons(geometry) -> list[Polygon]:
    """The polygons of a geometry, however nested (its lines and points dropped)."""
    out: list[Polygon] = []
    for part in shapely.get_parts(geometry):
        if isinstance(part, Polygon):
            out += [] if part.is_empty else [part]
        elif part.geom_type in ("MultiPolygon", "GeometryCollection"):
            out += _polygons(part)
    return out


def _filled(polygon: Polygon, min_hole_area: float) -> Polygon:
    """The polygon with its holes smaller than `min_hole_area` filled."""
    holes = [ring for ring in polygon.interiors if Polygon(ring).area >= min_hole_area]
    return Polygon(polygon.exterior, holes)


def _closed(points: np.ndarray) -> bool:
    return len(points) >= 4 and float(np.hypot(*(points[0, :2] - points[-1, :2]))) < _CLOSED_M
