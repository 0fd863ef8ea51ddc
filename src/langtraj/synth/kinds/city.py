"""City kind: a random street network from `netgenerate --rand`, with mixed junction types (signals,
priority, stop signs, all-way stops, right-before-left), sidewalks, crossings and maybe bike lanes. See docs/data.md."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import sumolib

from langtraj.synth.kinds.xmlfiles import KMH, SIGNAL_OPTIONS, chance, convert, integer, read_net, uniform
from langtraj.synth.network import BuiltNetwork, InterestCentre, NetworkKind, register_kind
from langtraj.synth.sumo import SynthError, run_tool

JUNCTION_TYPES: tuple[tuple[str, float], ...] = (
    ("traffic_light", 0.4),
    ("priority", 0.25),
    ("priority_stop", 0.15),
    ("allway_stop", 0.1),
    ("right_before_left", 0.1),
)
"""Types drawn for junctions of three or more roads, with their probabilities."""

MAX_SIGNAL_ROADS = 4
"""Largest junction (incoming roads) that may get a traffic light."""

MAX_CENTRES = 6
MIN_CENTRES = 3
ATTEMPTS = 20
"""netgenerate seeds tried until a network has MIN_CENTRES junctions of three or more incoming roads."""


def _generate(workdir: Path, seed: int, nodes: int) -> None:
    """Random plain network `city_gen.{nod,edg}.xml` of `nodes` nodes 60-110 m apart."""
    args = ["--rand", "--seed", str(seed), "--rand.iterations", str(nodes)]
    args += ["--rand.min-distance", "60", "--rand.max-distance", "110", "--rand.min-angle", "50"]
    args += ["--default.lanenumber", "1", "--no-turnarounds", "true", "--plain-output-prefix", "city_gen"]
    args += ["--output-file", "city_gen.net.xml"]
    run_tool("netgenerate", args, cwd=workdir)


def _junction_degrees(edges: ET.Element) -> dict[str, int]:
    """Number of incoming edges per node id."""
    degree: dict[str, int] = {}
    for edge in edges.iter("edge"):
        degree[edge.get("to", "")] = degree.get(edge.get("to", ""), 0) + 1
    return degree


def _draw_types(rng: np.random.Generator, nodes: ET.Element, degree: dict[str, int]) -> dict[str, str]:
    """Draw a type for each junction of three or more roads (sorted by id); set it on the node.

    Junctions of more than MAX_SIGNAL_ROADS roads get no signal: the incoming layout gives every road its
    own phase, and with five or more the red time passes SUMO's 90 s teleport time.
    """
    types = {}
    for node in sorted(nodes.iter("node"), key=lambda n: n.get("id", "")):
        node_id = node.get("id", "")
        roads = degree.get(node_id, 0)
        if roads >= 3:
            allowed = [(t, p) for t, p in JUNCTION_TYPES if roads <= MAX_SIGNAL_ROADS or t != "traffic_light"]
            probs = np.array([p for _, p in allowed])
            types[node_id] = allowed[int(rng.choice(len(allowed), p=probs / probs.sum()))][0]
            node.set("type", types[node_id])
        else:
            node.set("type", "priority")
    return types


def _draw_roads(rng: np.random.Generator, edges: ET.Element) -> dict[str, list[float]]:
    """Draw [lanes, speed km/h, priority] per road (both directions alike, roads sorted by id); set them
    on the edges."""
    roads: dict[str, list[float]] = {}
    for road in sorted({e.get("id", "").lstrip("-") for e in edges.iter("edge")}):
        roads[road] = [2 if chance(rng, 0.25) else 1, uniform(rng, 30.0, 50.0), integer(rng, 1, 3)]
    for edge in edges.iter("edge"):
        lanes, speed_kmh, priority = roads[edge.get("id", "").lstrip("-")]
        edge.set("numLanes", str(int(lanes)))
        edge.set("speed", f"{speed_kmh * KMH:.2f}")
        edge.set("priority", str(int(priority)))
    return roads


def _write(root: ET.Element, path: Path) -> None:
    """Write `root` without netgenerate's header comment (ElementTree drops comments)."""
    ET.indent(root)
    ET.ElementTree(root).write(path, encoding="UTF-8", xml_declaration=True)


def _centres(net: sumolib.net.Net) -> tuple[InterestCentre, ...]:
    """Junctions with >= 3 incoming vehicle roads, nearest the network's middle first, at most MAX_CENTRES."""
    xmin, ymin, xmax, ymax = net.getBoundary()
    mx, my = (xmin + xmax) / 2, (ymin + ymax) / 2
    found = []
    for node in net.getNodes():
        incoming = [e for e in node.getIncoming() if e.getFunction() == "" and e.allows("passenger")]
        if len(incoming) >= 3:
            x, y = node.getCoord()[:2]
            found.append((round(math.hypot(x - mx, y - my), 3), node.getID(), x, y))
    found.sort()
    return tuple(
        InterestCentre(round(x, 2), round(y, 2), 45.0, "junction", nid) for _, nid, x, y in found[:MAX_CENTRES]
    )


def _convert(workdir: Path, bikes: bool, timing: Sequence[str]) -> Path:
    """netconvert the drawn plain files with sidewalks, crossings, signals (and bike lanes)."""
    args = ["--node-files", "city.nod.xml", "--edge-files", "city.edg.xml", *SIGNAL_OPTIONS, *timing]
    args += ["--sidewalks.guess", "true", "--sidewalks.guess.max-speed", "15", "--crossings.guess", "true"]
    if bikes:
        args += ["--bikelanes.guess", "true", "--bikelanes.guess.max-speed", "15"]
    return convert(args, workdir, "city", bike_lanes=bikes)


@register_kind
class City(NetworkKind):
    """Random city street network of a few hundred metres with mixed junction types."""

    name = "city"
    description = "random city streets (netgenerate --rand) with signals, stop signs, all-way stops, crosswalks"

    def build(self, rng: np.random.Generator, workdir: Path) -> BuiltNetwork:
        """Draw the size, a netgenerate seed, junction types, road lanes/speeds, bike lanes and timing."""
        workdir.mkdir(parents=True, exist_ok=True)
        size = integer(rng, 14, 20)
        bikes = chance(rng, 0.5)
        green, yellow = integer(rng, 10, 15), integer(rng, 3, 4)
        timing = ["--tls.green.time", str(green), "--tls.yellow.time", str(yellow)]
        base_seed = integer(rng, 0, 2**30)
        for attempt in range(ATTEMPTS):
            _generate(workdir, base_seed + attempt, size)
            nodes = ET.parse(workdir / "city_gen.nod.xml").getroot()
            edges = ET.parse(workdir / "city_gen.edg.xml").getroot()
            types = _draw_types(rng, nodes, _junction_degrees(edges))
            roads = _draw_roads(rng, edges)
            _write(nodes, workdir / "city.nod.xml")
            _write(edges, workdir / "city.edg.xml")
            net_file = _convert(workdir, bikes, timing)
            centres = _centres(read_net(net_file))
            if len(centres) >= MIN_CENTRES:
                break
        else:
            raise SynthError(f"city: no network with {MIN_CENTRES} junctions in {ATTEMPTS} netgenerate seeds")
        for name in ("nod", "edg", "con", "tll", "net"):
            (workdir / f"city_gen.{name}.xml").unlink(missing_ok=True)
        params: dict[str, object] = {
            "nodes": size,
            "netgenerate_seed": base_seed + attempt,
            "bike_lanes": bikes,
            "green_s": green,
            "yellow_s": yellow,
            "junction_types": types,
            "roads_lanes_speed_priority": roads,
        }
        return BuiltNetwork(self.name, net_file, centres, params, pedestrians=True, bicycles=bikes)
