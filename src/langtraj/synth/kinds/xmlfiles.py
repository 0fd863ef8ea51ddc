"""Plain-XML network descriptions (nodes, edges, connections, crossings, roundabouts) and the netconvert
call every hand-built kind shares, so each kind only draws geometry and says what goes where. See docs/data.md."""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import sumolib

from langtraj.synth.network import BuiltNetwork, InterestCentre
from langtraj.synth.sumo import run_tool

KMH = 1.0 / 3.6
"""Factor from km/h to m/s."""

SIGNAL_OPTIONS: tuple[str, ...] = ("--tls.layout", "incoming", "--tls.allred.time", "2")
"""netconvert options of every signalized kind (the default layout let vehicles collide in junctions)."""


def waiting_point_options(bike_lanes: bool) -> tuple[str, ...]:
    """netconvert's assumed vehicle width for placing the waiting points of turning vehicles inside
    junctions, chosen by measurement (collisions per simulated hour, ours and SUMO's junction checks).

    With bike lanes 0.5 m: at 1.8 m (the default) a car turning right waited for the crosswalk with its
    front on the bike path and cyclists hit it. Without bike lanes 2.6 m: at smaller widths a bus waiting
    to turn left stuck out into the oncoming lane.
    """
    return ("--internal-junctions.vehicle-width", "0.5" if bike_lanes else "2.6")


_HEADER = re.compile(r"<!--.*?-->\s*", re.DOTALL)


@dataclass(frozen=True)
class Node:
    """A plain-XML node: id, position in metres and netconvert junction type."""

    id: str
    x: float
    y: float
    type: str = "priority"


@dataclass(frozen=True)
class Edge:
    """A plain-XML edge. `sidewalk` / `bike_lane` are lane widths in metres (0: none); `shape` is an
    optional polyline (start and end included) for curved edges."""

    id: str
    from_node: str
    to_node: str
    lanes: int
    speed: float
    priority: int = 1
    sidewalk: float = 0.0
    bike_lane: float = 0.0
    shape: tuple[tuple[float, float], ...] = ()
    lane_width: float = 0.0


@dataclass(frozen=True)
class Connection:
    """A lane-to-lane connection between two edges (lane indices include sidewalk / bike lanes)."""

    from_edge: str
    to_edge: str
    from_lane: int
    to_lane: int


@dataclass(frozen=True)
class Crossing:
    """A pedestrian crossing over `edges` at `node`; `priority` gives pedestrians right of way."""

    node: str
    edges: tuple[str, ...]
    priority: bool = False
    width: float = 4.0


@dataclass(frozen=True)
class PlainNetwork:
    """Everything netconvert needs to build one hand-drawn network."""

    nodes: tuple[Node, ...]
    edges: tuple[Edge, ...]
    connections: tuple[Connection, ...] = ()
    crossings: tuple[Crossing, ...] = ()
    roundabouts: tuple[tuple[tuple[str, ...], tuple[str, ...]], ...] = ()
    """(node ids, edge ids) of each roundabout."""
    options: tuple[str, ...] = field(default=())
    """Extra netconvert options of this kind."""


def polar(radius: float, angle_deg: float) -> tuple[float, float]:
    """Point at `radius` metres from the origin in direction `angle_deg` (counter-clockwise from east)."""
    a = math.radians(angle_deg)
    return (round(radius * math.cos(a), 2), round(radius * math.sin(a), 2))


def two_way(
    a: str, b: str, lanes: int, speed: float, *, sidewalk: float = 0.0, bike_lane: float = 0.0, priority: int = 1
) -> tuple[Edge, Edge]:
    """The edges `a_b` and `b_a` of a two-way road between nodes `a` and `b`."""
    common = {"lanes": lanes, "speed": speed, "priority": priority, "sidewalk": sidewalk, "bike_lane": bike_lane}
    return Edge(f"{a}_{b}", a, b, **common), Edge(f"{b}_{a}", b, a, **common)


@dataclass(frozen=True)
class Arm:
    """One approach of a junction: a two-way road from an outer (fringe) node towards the junction.

    `bay_length` > 0 adds a left-turn bay: the last `bay_length` metres of the inbound road get one more
    lane (netconvert then makes the leftmost lane a dedicated left-turn lane).
    """

    name: str
    angle: float
    length: float
    lanes_in: int
    lanes_out: int
    speed: float
    priority: int = 1
    sidewalk: float = 0.0
    bike_lane: float = 0.0
    bay_length: float = 0.0


def arm_elements(junction: str, origin: tuple[float, float], arm: Arm) -> tuple[list[Node], list[Edge]]:
    """Nodes and edges of `arm` joining node `junction` at `origin`: `<name>_in`, `<name>_out` (and
    `<name>_bay` when the arm has a left-turn bay)."""
    side = {"sidewalk": arm.sidewalk, "bike_lane": arm.bike_lane, "priority": arm.priority}
    ox, oy = origin
    dx, dy = polar(arm.length, arm.angle)
    outer = Node(arm.name, round(ox + dx, 2), round(oy + dy, 2))
    nodes, edges = [outer], [Edge(f"{arm.name}_out", junction, arm.name, arm.lanes_out, arm.speed, **side)]
    if arm.bay_length > 0:
        bx, by = polar(arm.bay_length, arm.angle)
        bay = Node(f"{arm.name}_b", round(ox + bx, 2), round(oy + by, 2))
        nodes.append(bay)
        edges.append(Edge(f"{arm.name}_in", arm.name, bay.id, arm.lanes_in, arm.speed, **side))
        edges.append(Edge(f"{arm.name}_bay", bay.id, junction, arm.lanes_in + 1, arm.speed, **side))
    else:
        edges.append(Edge(f"{arm.name}_in", arm.name, junction, arm.lanes_in, arm.speed, **side))
    return nodes, edges


def star(centre: Node, arms: Sequence[Arm], options: Sequence[str], zebras: bool = False) -> PlainNetwork:
    """A single junction `centre` with `arms` around it; `zebras` adds a crossing with pedestrian
    priority over every arm (arms need sidewalks)."""
    nodes, edges, crossings = [centre], [], []
    for arm in arms:
        arm_nodes, arm_edges = arm_elements(centre.id, (centre.x, centre.y), arm)
        nodes += arm_nodes
        edges += arm_edges
        if zebras:
            inbound = f"{arm.name}_bay" if arm.bay_length > 0 else f"{arm.name}_in"
            crossings.append(Crossing(centre.id, (inbound, f"{arm.name}_out"), priority=True))
    return PlainNetwork(tuple(nodes), tuple(edges), crossings=tuple(crossings), options=tuple(options))


def rotate(plain: PlainNetwork, angle_deg: float) -> PlainNetwork:
    """`plain` turned by `angle_deg` about the origin (nodes and edge shapes), so scenes face any way."""
    c, s = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))

    def turn(x: float, y: float) -> tuple[float, float]:
        return (round(c * x - s * y, 2), round(s * x + c * y, 2))

    nodes = tuple(replace(n, x=turn(n.x, n.y)[0], y=turn(n.x, n.y)[1]) for n in plain.nodes)
    edges = tuple(replace(e, shape=tuple(turn(x, y) for x, y in e.shape)) for e in plain.edges)
    return replace(plain, nodes=nodes, edges=edges)


def uniform(rng: np.random.Generator, low: float, high: float, digits: int = 1) -> float:
    """A uniform draw rounded to `digits` (rounded so the drawn value written to XML and params agree)."""
    return round(float(rng.uniform(low, high)), digits)


def integer(rng: np.random.Generator, low: int, high: int) -> int:
    """A uniform integer in [low, high] (both included)."""
    return int(rng.integers(low, high + 1))


def chance(rng: np.random.Generator, p: float) -> bool:
    """True with probability `p`."""
    return bool(rng.random() < p)


def build(plain: PlainNetwork, workdir: Path, stem: str) -> Path:
    """Write the plain XML files of `plain` into `workdir` and run netconvert there; return the net file.

    Paths are relative to `workdir` and netconvert's header comment (date, configuration) is removed, so
    the same description gives a byte-identical net file in any folder.
    """
    workdir.mkdir(parents=True, exist_ok=True)
    files = {"nod": _nodes_xml(plain.nodes), "edg": _edges_xml(plain.edges, plain.roundabouts)}
    if plain.connections or plain.crossings:
        files["con"] = _connections_xml(plain.connections, plain.crossings)
    names = {}
    for suffix, root in files.items():
        name = f"{stem}.{suffix}.xml"
        ET.indent(root)
        ET.ElementTree(root).write(workdir / name, encoding="UTF-8", xml_declaration=True)
        names[suffix] = name
    args = ["--node-files", names["nod"], "--edge-files", names["edg"]]
    if "con" in names:
        args += ["--connection-files", names["con"]]
    bike_lanes = any(e.bike_lane > 0 for e in plain.edges)
    return convert(args + list(plain.options), workdir, stem, bike_lanes=bike_lanes)


def built_junctions(
    kind: str,
    plain: PlainNetwork,
    workdir: Path,
    junctions: Sequence[str],
    radius: float,
    params: dict[str, object],
    *,
    pedestrians: bool,
    bicycles: bool,
) -> BuiltNetwork:
    """Build `plain` and describe it with one "junction" centre per node in `junctions`."""
    net_file = build(plain, workdir, kind)
    centres = junction_centres(read_net(net_file), junctions, radius)
    return BuiltNetwork(kind, net_file, centres, params, pedestrians=pedestrians, bicycles=bicycles)


def convert(args: Sequence[str], workdir: Path, stem: str, *, bike_lanes: bool) -> Path:
    """Run netconvert in `workdir` writing `<stem>.net.xml` (no U-turns anywhere); strip its header."""
    net_name = f"{stem}.net.xml"
    common = ["--output-file", net_name, "--no-turnarounds", "true", "--seed", "0", *waiting_point_options(bike_lanes)]
    run_tool("netconvert", [*args, *common], cwd=workdir)
    return strip_header(workdir / net_name)


def strip_header(path: Path) -> Path:
    """Remove the comment SUMO tools write before the root element (date, configuration, paths)."""
    text = path.read_text(encoding="utf-8")
    declaration, sep, rest = text.partition("?>")
    if sep:
        rest = _HEADER.sub("", rest.lstrip(), count=1) if rest.lstrip().startswith("<!--") else rest.lstrip()
        text = f"{declaration}{sep}\n\n{rest}"
    path.write_text(text, encoding="utf-8")
    return path


def read_net(net_file: Path) -> sumolib.net.Net:
    """The net as sumolib reads it for simulation (internal lanes and pedestrian connections included)."""
    return sumolib.net.readNet(str(net_file), withInternal=True, withPedestrianConnections=True)


def junction_centres(
    net: sumolib.net.Net, node_ids: Iterable[str], radius: float, label: str = "junction"
) -> tuple[InterestCentre, ...]:
    """InterestCentres at the built positions of `node_ids` (net coordinates, after netconvert's offset)."""
    centres = []
    for node_id in node_ids:
        x, y = net.getNode(node_id).getCoord()[:2]
        centres.append(InterestCentre(round(x, 2), round(y, 2), radius, label, node_id))
    return tuple(centres)


def net_point(net: sumolib.net.Net, x: float, y: float) -> tuple[float, float]:
    """A point of the plain description moved into net coordinates (netconvert shifts by the offset)."""
    dx, dy = net.getLocationOffset()[:2]
    return (round(x + dx, 2), round(y + dy, 2))


def _fmt(value: float) -> str:
    return f"{value:.2f}"


def _nodes_xml(nodes: Sequence[Node]) -> ET.Element:
    root = ET.Element("nodes")
    for n in nodes:
        ET.SubElement(root, "node", id=n.id, x=_fmt(n.x), y=_fmt(n.y), type=n.type)
    return root


def _edges_xml(edges: Sequence[Edge], roundabouts: Sequence[tuple[Sequence[str], Sequence[str]]]) -> ET.Element:
    root = ET.Element("edges")
    for e in edges:
        attrs = {
            "id": e.id,
            "from": e.from_node,
            "to": e.to_node,
            "priority": str(e.priority),
            "numLanes": str(e.lanes),
            "speed": _fmt(e.speed),
        }
        if e.sidewalk > 0:
            attrs["sidewalkWidth"] = _fmt(e.sidewalk)
        if e.bike_lane > 0:
            attrs["bikeLaneWidth"] = _fmt(e.bike_lane)
        if e.lane_width > 0:
            attrs["width"] = _fmt(e.lane_width)
        if e.shape:
            attrs["shape"] = " ".join(f"{_fmt(x)},{_fmt(y)}" for x, y in e.shape)
        ET.SubElement(root, "edge", attrs)
    for node_ids, edge_ids in roundabouts:
        ET.SubElement(root, "roundabout", nodes=" ".join(node_ids), edges=" ".join(edge_ids))
    return root


def _connections_xml(connections: Sequence[Connection], crossings: Sequence[Crossing]) -> ET.Element:
    root = ET.Element("connections")
    for c in connections:
        ET.SubElement(
            root,
            "connection",
            {"from": c.from_edge, "to": c.to_edge, "fromLane": str(c.from_lane), "toLane": str(c.to_lane)},
        )
    for x in crossings:
        attrs = {
            "node": x.node,
            "edges": " ".join(x.edges),
            "priority": str(x.priority).lower(),
            "width": _fmt(x.width),
        }
        ET.SubElement(root, "crossing", attrs)
    return root
