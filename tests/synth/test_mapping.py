"""SUMO network -> map model: small networks built with netconvert, checked for topology and geometry."""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import shapely
from shapely.geometry import LinearRing, LineString, Point, Polygon
from shapely.ops import linemerge

from langtraj.scenario import Agents, MapFeature, MapFeatureType, RoadMap, Scenario, TrafficLights
from langtraj.scenario.io.womd import scenario_from_proto, scenario_to_proto

sumolib = pytest.importorskip("sumolib", reason="SUMO (sumolib, eclipse-sumo) is not installed")

from langtraj.synth.mapping import NetMap, build_net_map, crop_road_map  # noqa: E402  (needs sumolib)
from langtraj.synth.mapping.common import DRIVABLE_CLASSES  # noqa: E402
from langtraj.synth.mapping.geometry import offset_polyline  # noqa: E402
from langtraj.synth.mapping.network import is_intersection  # noqa: E402
from langtraj.synth.sumo import run_tool  # noqa: E402
from langtraj.viz import RenderConfig, render_frame  # noqa: E402

FOUR_WAY = (
    """<nodes>
  <node id="C" x="0" y="0" type="traffic_light"/>
  <node id="N" x="0" y="100"/><node id="S" x="0" y="-100"/><node id="E" x="100" y="0"/><node id="W" x="-100" y="0"/>
</nodes>""",
    "<edges>"
    + "".join(
        f'<edge id="{a}{b}" from="{a}" to="{b}" numLanes="2" speed="13.89"/>'
        for arm in "NSEW"
        for a, b in ((arm, "C"), ("C", arm))
    )
    + "</edges>",
    ["--sidewalks.guess", "--crossings.guess", "--tls.layout", "incoming"],
)

T_STOP = (
    """<nodes>
  <node id="J" x="0" y="0" type="priority_stop"/>
  <node id="W" x="-80" y="0"/><node id="E" x="80" y="0"/><node id="S" x="0" y="-80"/>
</nodes>""",
    """<edges>
  <edge id="WJ" from="W" to="J" numLanes="1" speed="13.89" priority="3"/>
  <edge id="JW" from="J" to="W" numLanes="1" speed="13.89" priority="3"/>
  <edge id="EJ" from="E" to="J" numLanes="1" speed="13.89" priority="3"/>
  <edge id="JE" from="J" to="E" numLanes="1" speed="13.89" priority="3"/>
  <edge id="SJ" from="S" to="J" numLanes="2" speed="11.11" priority="1"/>
  <edge id="JS" from="J" to="S" numLanes="1" speed="11.11" priority="1"/>
</edges>""",
    [],
)

LANE_DROP = (
    """<nodes><node id="A" x="0" y="0"/><node id="B" x="120" y="10"/><node id="C" x="240" y="10"/></nodes>""",
    """<edges>
  <edge id="AB" from="A" to="B" numLanes="4" speed="25">
    <lane index="0" allow="bicycle" width="1.8"/>
    <lane index="1" changeLeft="emergency"/><lane index="2" changeRight="emergency"/>
  </edge>
  <edge id="BC" from="B" to="C" numLanes="3" speed="25"><lane index="0" allow="bicycle" width="1.8"/></edge>
  <edge id="CB" from="C" to="B" numLanes="1" speed="25"/>
  <edge id="BA" from="B" to="A" numLanes="1" speed="25"/>
</edges>""",
    [],
)

NETS = {"four_way": FOUR_WAY, "t_stop": T_STOP, "lane_drop": LANE_DROP}


@dataclass(frozen=True)
class Built:
    net_file: Path
    net: sumolib.net.Net
    netmap: NetMap

    def feature(self, sumo_lane: str) -> MapFeature:
        return self.netmap.road_map.by_id[self.netmap.lane_ids[sumo_lane]]


@pytest.fixture(scope="module")
def built(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Built]:
    folder = tmp_path_factory.mktemp("nets")
    result = {}
    for name, (nodes, edges, options) in NETS.items():
        (folder / f"{name}.nod.xml").write_text(nodes)
        (folder / f"{name}.edg.xml").write_text(edges)
        net_file = folder / f"{name}.net.xml"
        args = ["-n", f"{name}.nod.xml", "-e", f"{name}.edg.xml", "-o", net_file.name, *options]
        run_tool("netconvert", args, cwd=folder)
        net = sumolib.net.readNet(str(net_file), withInternal=True, withPedestrianConnections=True)
        result[name] = Built(net_file, net, build_net_map(net_file))
    return result


ALL = pytest.mark.parametrize("name", list(NETS))


def _drivable(lane) -> bool:
    return bool(DRIVABLE_CLASSES & set(lane.getPermissions()))


def _sumo_lanes(net):
    for edge in net.getEdges(withInternal=True):
        for lane in edge.getLanes():
            yield edge, lane


def _vehicle_connections(net):
    for edge, lane in _sumo_lanes(net):
        if edge.getFunction() in ("", "internal") and _drivable(lane):
            yield from lane.getOutgoing()


# ---------------------------------------------------------------------------------------------- lanes


@ALL
def test_every_drivable_lane_is_a_lane_feature(built: dict[str, Built], name: str) -> None:
    b = built[name]
    expected = {
        lane.getID() for edge, lane in _sumo_lanes(b.net) if edge.getFunction() in ("", "internal") and _drivable(lane)
    }
    assert set(b.netmap.lane_ids) == expected
    assert len(b.netmap.road_map.lanes) == len(expected)
    for lane_id in expected:
        f = b.feature(lane_id)
        sumo_lane = b.net.getLane(lane_id)
        assert f.type.is_lane and len(f.points) >= 2 and np.isfinite(f.points).all()
        internal = lane_id.startswith(":")
        assert f.interpolating == (internal and is_intersection(sumo_lane.getEdge().getFromNode()))
        assert f.speed_limit_mph == pytest.approx(sumo_lane.getSpeed() / 0.44704)
        # points follow the SUMO lane shape (resampled): same ends, every SUMO vertex on the polyline
        shape = np.asarray(sumo_lane.getShape())
        assert np.allclose(f.points[[0, -1], :2], shape[[0, -1]])
        assert LineString(f.points[:, :2]).distance(shapely.MultiPoint(shape)) < 1e-6
        assert np.linalg.norm(np.diff(f.points[:, :2], axis=0), axis=1).max() <= 0.5 + 1e-9


def test_sidewalks_crossings_and_walking_areas_are_not_lanes(built: dict[str, Built]) -> None:
    b = built["four_way"]
    assert "NC_0" not in b.netmap.lane_ids  # sidewalk
    assert not [k for k in b.netmap.lane_ids if "_c" in k or "_w" in k]
    assert b.netmap.junction_of_lane[":C_0_0"] == "C"
    assert b.netmap.junction_of_lane[":C_c0_0"] == "C"


def test_lane_types(built: dict[str, Built]) -> None:
    drop = built["lane_drop"]
    assert drop.feature("AB_0").type == MapFeatureType.LANE_BIKE_LANE
    assert drop.feature(":B_1_0").type == MapFeatureType.LANE_BIKE_LANE
    assert drop.feature("AB_1").type == MapFeatureType.LANE_FREEWAY  # 25 m/s
    assert drop.feature(":B_1_1").type == MapFeatureType.LANE_FREEWAY
    types = {f.type for f in built["four_way"].netmap.road_map.lanes}
    assert types == {MapFeatureType.LANE_SURFACE_STREET}


@ALL
def test_connectivity_follows_sumo_connections(built: dict[str, Built], name: str) -> None:
    b = built[name]
    ids = b.netmap.lane_ids
    expected: dict[int, set[int]] = {fid: set() for fid in ids.values()}
    for conn in _vehicle_connections(b.net):
        nxt = conn.getViaLaneID() or conn.getToLane().getID()
        expected[ids[conn.getFromLane().getID()]].add(ids[nxt])
    by_id = b.netmap.road_map.by_id
    for fid, exits in expected.items():
        assert set(by_id[fid].exit_lanes) == exits
    for lane in b.netmap.road_map.lanes:
        for nxt in lane.exit_lanes:
            assert lane.id in by_id[nxt].entry_lanes
        for prev in lane.entry_lanes:
            assert lane.id in by_id[prev].exit_lanes


def test_connectivity_examples(built: dict[str, Built]) -> None:
    b = built["four_way"]
    ids = b.netmap.lane_ids
    # NC_2 turns left via the split internal lanes :C_3_0 -> :C_21_0 into CE_2
    assert ids[":C_3_0"] in b.feature("NC_2").exit_lanes
    assert b.feature(":C_3_0").exit_lanes == (ids[":C_21_0"],)
    assert b.feature(":C_21_0").exit_lanes == (ids["CE_2"],)
    assert ids[":C_21_0"] in b.feature("CE_2").entry_lanes
    drop = built["lane_drop"]
    assert drop.feature("AB_3").exit_lanes == ()  # the dropped lane ends


@ALL
def test_neighbours_are_symmetric_and_span_the_lanes(built: dict[str, Built], name: str) -> None:
    road_map = built[name].netmap.road_map
    by_id = road_map.by_id
    for lane in road_map.lanes:
        for side, back in (("left_neighbors", "right_neighbors"), ("right_neighbors", "left_neighbors")):
            for nb in getattr(lane, side):
                other = by_id[nb.feature_id]
                assert [n.feature_id for n in getattr(other, back)] == [lane.id]
                assert (nb.self_start_index, nb.self_end_index) == (0, len(lane.points) - 1)
                assert (nb.neighbor_start_index, nb.neighbor_end_index) == (0, len(other.points) - 1)
                for seg in nb.boundaries:
                    assert by_id[seg.boundary_feature_id].type.is_road_line
    b = built["four_way"]
    assert [n.feature_id for n in b.feature("NC_1").left_neighbors] == [b.netmap.lane_ids["NC_2"]]
    assert b.feature("NC_1").right_neighbors == ()  # the sidewalk is no neighbour
    assert [n.feature_id for n in b.feature(":C_1_0").left_neighbors] == [b.netmap.lane_ids[":C_1_1"]]


# ---------------------------------------------------------------------------------------------- boundaries, lines


@ALL
def test_boundaries_reference_existing_lines_and_edges(built: dict[str, Built], name: str) -> None:
    road_map = built[name].netmap.road_map
    by_id = road_map.by_id
    internal = {fid for sid, fid in built[name].netmap.lane_ids.items() if sid.startswith(":")}
    for lane in road_map.lanes:
        if lane.id not in internal:
            assert lane.left_boundaries and lane.right_boundaries, lane.id
        for seg in (*lane.left_boundaries, *lane.right_boundaries):
            target = by_id[seg.boundary_feature_id]
            assert 0 <= seg.lane_start_index < seg.lane_end_index < len(lane.points)
            if seg.boundary_type == MapFeatureType.ROAD_LINE_UNKNOWN:
                assert target.type.is_road_edge
            else:
                assert target.type == seg.boundary_type and target.type.is_road_line


def _boundary_types(f: MapFeature, side: str) -> set[MapFeatureType]:
    return {s.boundary_type for s in getattr(f, f"{side}_boundaries")}


def test_road_line_types(built: dict[str, Built]) -> None:
    b = built["four_way"]
    assert _boundary_types(b.feature("NC_1"), "left") == {MapFeatureType.ROAD_LINE_BROKEN_SINGLE_WHITE}
    assert _boundary_types(b.feature("NC_2"), "left") == {MapFeatureType.ROAD_LINE_SOLID_DOUBLE_YELLOW}
    assert _boundary_types(b.feature("NC_1"), "right") == {MapFeatureType.ROAD_LINE_UNKNOWN}  # the road edge
    drop = built["lane_drop"]
    assert _boundary_types(drop.feature("AB_1"), "right") == {MapFeatureType.ROAD_LINE_SOLID_SINGLE_WHITE}  # bike
    assert _boundary_types(drop.feature("AB_1"), "left") == {MapFeatureType.ROAD_LINE_SOLID_SINGLE_WHITE}  # no change
    assert _boundary_types(drop.feature("AB_2"), "left") == {MapFeatureType.ROAD_LINE_BROKEN_SINGLE_WHITE}
    assert _boundary_types(drop.feature("BA_0"), "left") == {MapFeatureType.ROAD_LINE_SOLID_DOUBLE_YELLOW}
    # one double yellow line per pair of opposite edges
    pairs = {"four_way": 4, "t_stop": 3, "lane_drop": 2}
    for name, count in pairs.items():
        yellow = built[name].netmap.road_map.of_type(MapFeatureType.ROAD_LINE_SOLID_DOUBLE_YELLOW)
        assert len(yellow) == count


@ALL
def test_road_lines_lie_between_their_lanes(built: dict[str, Built], name: str) -> None:
    b = built[name]
    by_id = b.netmap.road_map.by_id
    widths = {b.netmap.lane_ids[k]: b.net.getLane(k).getWidth() for k in b.netmap.lane_ids}
    for lane in b.netmap.road_map.lanes:
        for seg in (*lane.left_boundaries, *lane.right_boundaries):
            target = by_id[seg.boundary_feature_id]
            if target.type.is_road_line:
                gap = shapely.distance(shapely.points(target.points[:, :2]), LineString(lane.points[:, :2]))
                assert np.allclose(gap, widths[lane.id] / 2.0, atol=0.05)
    lines = b.netmap.road_map.road_lines
    area = b.netmap.drivable_area
    assert all(area.buffer(0.05).contains(LineString(line.points[:, :2])) for line in lines)


# ---------------------------------------------------------------------------------------------- road edges


def _rings(road_map: RoadMap) -> list[LinearRing]:
    """The road edge pieces merged back into closed rings."""
    merged = linemerge([LineString(f.points[:, :2]) for f in road_map.road_edges])
    parts = getattr(merged, "geoms", [merged])
    assert all(p.is_ring for p in parts), "road edge pieces do not close into rings"
    return [LinearRing(p.coords) for p in parts]


def _area_from_edges(road_map: RoadMap):
    """Drivable area rebuilt from the road edges: counter-clockwise rings bound it, clockwise ones are holes."""
    rings = _rings(road_map)
    outer = shapely.union_all([Polygon(r) for r in rings if r.is_ccw])
    holes = [Polygon(r) for r in rings if not r.is_ccw]
    return outer.difference(shapely.union_all(holes)) if holes else outer


@ALL
def test_road_edges_bound_the_drivable_area(built: dict[str, Built], name: str) -> None:
    b = built[name]
    area = _area_from_edges(b.netmap.road_map)
    assert area.symmetric_difference(b.netmap.drivable_area).area < 1.0
    inside = area.buffer(0.05)
    for lane in b.netmap.road_map.lanes:
        assert shapely.contains(inside, shapely.points(lane.points[:, :2])).all(), lane.id
    # the outer border of each outermost lane runs along a road edge
    edges = shapely.union_all([LineString(f.points[:, :2]) for f in b.netmap.road_map.road_edges])
    internal = {fid for sid, fid in b.netmap.lane_ids.items() if sid.startswith(":")}
    for lane in b.netmap.road_map.lanes:
        for side, sign in (("left", 1.0), ("right", -1.0)):
            if lane.id in internal or _boundary_types(lane, side) != {MapFeatureType.ROAD_LINE_UNKNOWN}:
                continue
            width = b.net.getLane(next(k for k, v in b.netmap.lane_ids.items() if v == lane.id)).getWidth()
            border = offset_polyline(lane.points, sign * width / 2.0)
            assert shapely.distance(shapely.points(border[:, :2]), edges).max() < 0.5, (lane.id, side)


def _netconvert(folder: Path, nodes: str, edges: str) -> Path:
    (folder / "x.nod.xml").write_text(nodes)
    (folder / "x.edg.xml").write_text(edges)
    run_tool("netconvert", ["-n", "x.nod.xml", "-e", "x.edg.xml", "-o", "x.net.xml", "--no-turnarounds"], cwd=folder)
    return folder / "x.net.xml"


def _edge_kinds(road_map: RoadMap) -> list[tuple[MapFeatureType, bool]]:
    """(type, counter-clockwise) of each road edge ring (pieces merged)."""
    kinds = []
    for kind in (MapFeatureType.ROAD_EDGE_BOUNDARY, MapFeatureType.ROAD_EDGE_MEDIAN):
        kinds += [(kind, ring.is_ccw) for ring in _rings(RoadMap(tuple(road_map.of_type(kind))))]
    return sorted(kinds)


def test_holes_are_medians_or_block_boundaries(tmp_path: Path) -> None:
    nodes = """<nodes><node id="W" x="-50" y="0"/><node id="A" x="0" y="0"/>
      <node id="B" x="60" y="0"/><node id="E" x="110" y="0"/></nodes>"""
    median = """<edges>
      <edge id="WA" from="W" to="A" numLanes="1"/><edge id="AW" from="A" to="W" numLanes="1"/>
      <edge id="BE" from="B" to="E" numLanes="1"/><edge id="EB" from="E" to="B" numLanes="1"/>
      <edge id="AB" from="A" to="B" numLanes="1" shape="0,0 10,-4 50,-4 60,0"/>
      <edge id="BA" from="B" to="A" numLanes="1" shape="60,0 50,4 10,4 0,0"/>
    </edges>"""
    netmap = build_net_map(_netconvert(tmp_path, nodes, median))
    # a divided stretch: the outer ring (counter-clockwise), the median between the carriageways (clockwise)
    assert _edge_kinds(netmap.road_map) == [
        (MapFeatureType.ROAD_EDGE_BOUNDARY, True),
        (MapFeatureType.ROAD_EDGE_MEDIAN, False),
    ]
    yellow = netmap.road_map.of_type(MapFeatureType.ROAD_LINE_SOLID_DOUBLE_YELLOW)
    assert len(yellow) == 2  # on the undivided ends only
    block = tmp_path / "block"
    block.mkdir()
    corners = {"A": (0, 0), "B": (80, 0), "C": (80, 80), "D": (0, 80)}
    nodes = "<nodes>" + "".join(f'<node id="{k}" x="{x}" y="{y}"/>' for k, (x, y) in corners.items()) + "</nodes>"
    ring = "ABCDA"
    edges = (
        "<edges>"
        + "".join(
            f'<edge id="{a}{b}" from="{a}" to="{b}" numLanes="1"/><edge id="{b}{a}" from="{b}" to="{a}" numLanes="1"/>'
            for a, b in itertools.pairwise(ring)
        )
        + "</edges>"
    )
    netmap = build_net_map(_netconvert(block, nodes, edges))
    # a city block: its kerb is a (clockwise) boundary, not a median
    assert _edge_kinds(netmap.road_map) == [
        (MapFeatureType.ROAD_EDGE_BOUNDARY, False),
        (MapFeatureType.ROAD_EDGE_BOUNDARY, True),
    ]
    _area_from_edges(netmap.road_map)


# ------------------------------------------------------------------------------------ signals, signs, crosswalks


def test_signal_links_cover_every_tls_link(built: dict[str, Built]) -> None:
    b = built["four_way"]
    ids = b.netmap.lane_ids
    vehicle_links = {conn.getTLLinkIndex(): conn for conn in _vehicle_connections(b.net) if conn.getTLSID() == "C"}
    assert len(vehicle_links) == 20
    signals = b.netmap.signals
    assert [(s.tls_id, s.link_index) for s in signals] == [("C", i) for i in sorted(vehicle_links)]
    for s in signals:
        conn = vehicle_links[s.link_index]
        incoming = b.feature(conn.getFromLane().getID())
        assert s.lane_id == ids[conn.getViaLaneID()]
        assert s.incoming_lane_id == incoming.id
        assert np.allclose(s.stop_point, incoming.points[-1])
        assert np.allclose(s.stop_point[:2], conn.getFromLane().getShape()[-1])
        assert s.direction == conn.getDirection()
    # the links fit the TrafficLights model (one entry per controlled lane)
    TrafficLights(
        [s.lane_id for s in signals], np.zeros((1, 20)), np.ones((1, 20), bool), [s.stop_point for s in signals]
    )
    assert built["t_stop"].netmap.signals == () and built["lane_drop"].netmap.signals == ()


def test_crosswalks_cover_the_crossings(built: dict[str, Built]) -> None:
    b = built["four_way"]
    assert sorted(b.netmap.crossing_ids) == [":C_c0", ":C_c1", ":C_c2", ":C_c3"]
    for crossing, fid in b.netmap.crossing_ids.items():
        f = b.netmap.road_map.by_id[fid]
        assert f.type == MapFeatureType.CROSSWALK and len(f.points) >= 4
        shape = np.asarray(b.net.getLane(f"{crossing}_0").getShape())
        polygon = Polygon(f.points[:, :2])
        assert polygon.is_valid and polygon.area == pytest.approx(4.0 * LineString(shape).length, rel=0.01)
        assert polygon.contains(Point(shape.mean(axis=0)))


def test_stop_signs_control_the_minor_road_only(built: dict[str, Built]) -> None:
    b = built["t_stop"]
    signs = b.netmap.road_map.of_type(MapFeatureType.STOP_SIGN)
    assert len(signs) == 1
    ids = b.netmap.lane_ids
    assert set(signs[0].controlled_lanes) == {ids["SJ_0"], ids["SJ_1"]}
    end = b.feature("SJ_0").points[-1, :2]
    assert 1.5 < np.linalg.norm(signs[0].points[0, :2] - end) < 2.5
    assert signs[0].points[0, 0] > end[0]  # right of a northbound lane: east
    assert not built["four_way"].netmap.road_map.of_type(MapFeatureType.STOP_SIGN)


# ---------------------------------------------------------------------------------------------- whole map


@ALL
def test_ids_are_small_unique_and_deterministic(built: dict[str, Built], name: str) -> None:
    b = built[name]
    again = build_net_map(b.net_file)
    first, second = b.netmap.road_map.features, again.road_map.features
    assert sorted(f.id for f in first) == list(range(len(first)))
    assert dict(again.lane_ids) == dict(b.netmap.lane_ids)
    assert [(f.id, f.type) for f in first] == [(f.id, f.type) for f in second]
    assert all(np.array_equal(f.points, g.points) for f, g in zip(first, second, strict=True))
    assert again.signals == b.netmap.signals


def _references(f: MapFeature) -> set[int]:
    refs = set(f.entry_lanes) | set(f.exit_lanes) | set(f.controlled_lanes)
    for nb in (*f.left_neighbors, *f.right_neighbors):
        refs |= {nb.feature_id, *(s.boundary_feature_id for s in nb.boundaries)}
    return refs | {s.boundary_feature_id for s in (*f.left_boundaries, *f.right_boundaries)}


@ALL
def test_crop_leaves_no_dangling_references(built: dict[str, Built], name: str) -> None:
    road_map = built[name].netmap.road_map
    allp = np.concatenate([f.points[:, :2] for f in road_map])
    centre = (allp.min(axis=0) + allp.max(axis=0)) / 2.0
    lo, hi = centre - 25.0, centre + 25.0
    cropped = crop_road_map(road_map, lo, hi)
    assert 0 < len(cropped) < len(road_map)
    kept = {f.id for f in cropped}
    for f in cropped:
        assert _references(f) <= kept
        assert np.all((f.points[:, :2] >= lo) & (f.points[:, :2] <= hi), axis=1).any()
    dropped = [f for f in road_map if f.id not in kept]
    for f in dropped:
        assert not np.all((f.points[:, :2] >= lo) & (f.points[:, :2] <= hi), axis=1).any()
    whole = crop_road_map(road_map, allp.min(axis=0), allp.max(axis=0))
    assert [f.id for f in whole] == [f.id for f in road_map]
    assert all(f is g for f, g in zip(whole, road_map, strict=True))  # unchanged features are shared
    assert len(crop_road_map(road_map, (1e6, 1e6), (1e6 + 1, 1e6 + 1))) == 0


def _scenario(netmap: NetMap, x: float, y: float) -> Scenario:
    states = np.zeros((1, 1, 9), np.float32)
    states[0, 0, :2] = (x, y)
    states[0, 0, 6:9] = (4.5, 2.0, 1.5)
    agents = Agents(ids=[1], types=[1], states=states, valid=np.ones((1, 1), bool))
    n = len(netmap.signals)
    lights = TrafficLights(
        [s.lane_id for s in netmap.signals],
        np.full((1, n), 4, np.int8),
        np.ones((1, n), bool),
        np.array([s.stop_point for s in netmap.signals]).reshape(n, 3),
    )
    return Scenario("net", [0.0], 0, 0, agents, netmap.road_map, lights)


def test_womd_round_trip_keeps_the_map(built: dict[str, Built]) -> None:
    netmap = built["four_way"].netmap
    back = scenario_from_proto(scenario_to_proto(_scenario(netmap, 100.0, 100.0))).road_map
    assert [(f.id, f.type) for f in back] == [(f.id, f.type) for f in netmap.road_map]
    for f, g in zip(netmap.road_map, back, strict=True):
        assert np.allclose(f.points, g.points, atol=1e-3)
        assert (f.entry_lanes, f.exit_lanes, f.left_boundaries, f.right_boundaries, f.left_neighbors) == (
            g.entry_lanes,
            g.exit_lanes,
            g.left_boundaries,
            g.right_boundaries,
            g.left_neighbors,
        )


def test_renders(built: dict[str, Built]) -> None:
    netmap = built["four_way"].netmap
    image = render_frame(_scenario(netmap, 100.0, 100.0), 0, RenderConfig(size_px=128, follow_track_id=1))
    assert image.shape == (128, 128, 3) and image.std() > 0


def test_build_and_crop_repeatedly(built: dict[str, Built]) -> None:
    """Building and cropping work on repeated calls (speed is measured by benchmarks/synth.py)."""
    b = built["four_way"]
    netmap = build_net_map(b.net_file)
    crop_road_map(netmap.road_map, (0, 0), (1, 1))  # builds the cached index
    crops = [crop_road_map(netmap.road_map, (70 + k, 70), (130 + k, 130)) for k in range(20)]
    assert all(len(c) > 0 for c in crops)
    assert len(crops[0]) == len(crop_road_map(netmap.road_map, (70, 70), (130, 130)))
