"""Reading a SUMO net for the map: its drivable lanes, lane-change permissions, connectivity and
lane types, and which junctions are intersections. See docs/data.md.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections import defaultdict
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import sumolib

from langtraj.scenario.types import MapFeatureType
from langtraj.synth.mapping.common import (
    DRIVABLE_CLASSES,
    FREEWAY_EDGE_TYPE_PREFIXES,
    FREEWAY_EDGE_TYPES,
    FREEWAY_SPEED_MPS,
)
from langtraj.synth.mapping.geometry import _dedupe, densify

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
