"""Randomized traffic demand for a built network: vehicle types with drawn driver parameters, and flows of
cars, trucks, buses, cyclists and pedestrians between the network's fringe edges.

Vehicles get `<flow from= to=>` so SUMO routes them at departure (no duarouter run); only pairs with a
route are written. Every draw comes from the given numpy Generator, so a seed fixes the route file.

See docs/data.md.
"""

from __future__ import annotations

import itertools
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import sumolib

from langtraj.synth.network import BuiltNetwork

HIGHWAY_SPEED = 25.0
"""Source edges at least this fast (m/s, 90 km/h) get highway rates per lane."""

MAX_WALKS = 24
MAX_WALK_TRIES = 300
MAX_WALK_M = 400.0
"""Pedestrian flows: at most MAX_WALKS edge pairs, found among MAX_WALK_TRIES random candidates, whose
shortest walk crosses a road and is at most MAX_WALK_M metres long."""

MIN_RATE = 0.5
"""Flows below this many per hour are left out (they would hardly ever depart)."""


VEHICLE_CLASSES = ("passenger", "truck", "bus", "bicycle")
"""The SUMO vehicle classes the demand draws (persons walk)."""


@dataclass(frozen=True)
class Demand:
    """The route file written for one simulation, the values drawn for it (JSON-compatible), and for each
    vehicle class the edges where its trips may end (a vehicle that picks a new direction is routed on to
    one of them, `langtraj.synth.intents`)."""

    route_file: Path
    params: Mapping[str, object]
    sinks: Mapping[str, tuple[str, ...]] = field(default_factory=dict)


@dataclass(frozen=True)
class DemandProfile:
    """Ranges the demand of one network kind is drawn from (vehicles per hour per source lane, shares)."""

    lane_rate: tuple[float, float]
    lane_exponent: float = 1.0
    """A source's rate is the per-lane rate times lanes ** lane_exponent (below 1: wide entries are not
    fed in proportion, e.g. two-lane roundabout arms)."""
    minor_factor: tuple[float, float] = (1.0, 1.0)
    """Rate factor of sources with a lower road priority than the highest (minor roads, ramps)."""
    max_total: tuple[float, float] | None = None
    """When given, source rates are scaled down to a total drawn from this range if they exceed it
    (networks with many sources, e.g. the random city)."""
    highway_lane_rate: tuple[float, float] = (1000.0, 1450.0)
    truck_share: tuple[float, float] = (0.02, 0.06)
    bus_share: tuple[float, float] = (0.01, 0.03)
    bike_rate: tuple[float, float] = (80.0, 200.0)
    person_rate: tuple[float, float] = (150.0, 400.0)


PROFILES: dict[str, DemandProfile] = {
    "signalized": DemandProfile(lane_rate=(130.0, 220.0), person_rate=(300.0, 600.0)),
    "priority": DemandProfile(lane_rate=(250.0, 380.0), minor_factor=(0.3, 0.6), person_rate=(300.0, 600.0)),
    "allway": DemandProfile(lane_rate=(170.0, 260.0), person_rate=(300.0, 550.0)),
    "roundabout": DemandProfile(lane_rate=(200.0, 300.0), lane_exponent=0.5, person_rate=(250.0, 550.0)),
    "onramp": DemandProfile(lane_rate=(300.0, 600.0), truck_share=(0.05, 0.12)),
    "arterial": DemandProfile(lane_rate=(110.0, 190.0), person_rate=(300.0, 600.0)),
    "zebra": DemandProfile(lane_rate=(250.0, 420.0), person_rate=(250.0, 550.0)),
    "city": DemandProfile(lane_rate=(100.0, 180.0), max_total=(700.0, 1100.0), person_rate=(300.0, 600.0)),
}
"""Demand ranges per kind; kinds without an entry use DEFAULT_PROFILE."""

DEFAULT_PROFILE = DemandProfile(lane_rate=(120.0, 200.0))


@dataclass(frozen=True)
class _Flow:
    """A flow of one type between two edges at `rate` per hour."""

    type_id: str
    origin: str
    destination: str
    rate: float


def write_demand(network: BuiltNetwork, rng: np.random.Generator, duration_s: float, workdir: Path) -> Demand:
    """Draw vehicle types and flows for `network` and write `<kind>.rou.xml` into `workdir`.

    Flows run from t=0 to `duration_s`. Cyclists are added iff the network has bike lanes, pedestrians
    iff it has sidewalks; flows only join edge pairs that have a route for their class.
    """
    net = sumolib.net.readNet(str(network.net_file), withInternal=True, withPedestrianConnections=True)
    profile = PROFILES.get(network.kind, DEFAULT_PROFILE)
    params: dict[str, object] = {}
    root = ET.Element("routes")
    root.extend(_vehicle_types(rng, network, params))
    flows = _vehicle_flows(net, rng, profile, params)
    if network.bicycles:
        flows += _bike_flows(net, rng, profile, params)
    flows = [f for f in flows if f.rate >= MIN_RATE]
    for i, flow in enumerate(flows):
        root.append(_flow_element(f"f{i}_{flow.type_id}", flow, duration_s))
    person_flows = []
    if network.pedestrians:
        person_flows = [f for f in _person_flows(net, rng, profile, params) if f.rate >= MIN_RATE]
    for i, flow in enumerate(person_flows):
        root.append(_person_flow_element(f"p{i}", flow, duration_s))
    params.update(flows=len(flows), person_flows=len(person_flows))
    workdir.mkdir(parents=True, exist_ok=True)
    route_file = workdir / f"{network.kind}.rou.xml"
    ET.indent(root)
    ET.ElementTree(root).write(route_file, encoding="UTF-8", xml_declaration=True)
    sinks = {vclass: tuple(fringe_edges(net, vclass)[1]) for vclass in VEHICLE_CLASSES}
    return Demand(route_file, params, sinks)


# --- vehicle types ----------------------------------------------------------------------------------


def _draw(rng: np.random.Generator, low: float, high: float, digits: int = 2) -> float:
    """A uniform draw, rounded so the value written to XML and the one in params agree."""
    return round(float(rng.uniform(low, high)), digits)


def _driver(rng: np.random.Generator, assertive: bool) -> dict[str, str]:
    """Lane-change and junction parameters of one driver profile (`assertive` drivers gain speed more).

    Impatience is at least 0.3: fully patient drivers on a minor road (or a slow bus) can wait for a
    gap in the major stream until SUMO teleports them.
    """
    speed_gain = (1.0, 3.0) if assertive else (0.3, 1.2)
    values = {
        "lcStrategic": _draw(rng, 0.5, 2.0),
        "lcCooperative": _draw(rng, 0.6, 1.0),
        "lcSpeedGain": _draw(rng, *speed_gain),
        "lcKeepRight": _draw(rng, 0.3, 1.5),
        "lcAssertive": _draw(rng, 1.0, 2.5) if assertive else _draw(rng, 0.8, 1.5),
        "jmTimegapMinor": _draw(rng, 0.6, 1.5),
        "impatience": _draw(rng, 0.3, 0.8),
    }
    return {k: f"{v:g}" for k, v in values.items()}


def _speed_factor(rng: np.random.Generator, mean: tuple[float, float], dev: tuple[float, float]) -> str:
    """A per-vehicle speed factor distribution: normal, clipped, with a small drawn deviation."""
    m, d = _draw(rng, *mean), _draw(rng, *dev, digits=3)
    return f"normc({m:g},{d:g},{max(0.5, m - 3 * d):.2f},{m + 3 * d:.2f})"


def _vtype(type_id: str, vclass: str, rng: np.random.Generator, **ranges: tuple[float, float]) -> ET.Element:
    """A vType with IDM car following, sigma 0 and each of `ranges` drawn uniformly."""
    attrs = {"id": type_id, "vClass": vclass, "carFollowModel": "IDM", "sigma": "0"}
    attrs.update({name: f"{_draw(rng, lo, hi):g}" for name, (lo, hi) in ranges.items()})
    return ET.Element("vType", attrs)


def _car_types(rng: np.random.Generator) -> ET.Element:
    """A distribution `car` of 3 car driver profiles (one assertive) with drawn shares."""
    dist = ET.Element("vTypeDistribution", id="car")
    shares = rng.dirichlet(np.full(3, 3.0))
    for i, share in enumerate(shares):
        vtype = _vtype(
            f"car{i}",
            "passenger",
            rng,
            accel=(2.0, 3.2),
            decel=(3.8, 5.0),
            tau=(0.8, 1.5),
            minGap=(1.5, 3.0),
            length=(4.2, 5.0),
        )
        vtype.set("speedFactor", _speed_factor(rng, (0.95, 1.12), (0.04, 0.1)))
        vtype.attrib.update(_driver(rng, assertive=i == 0))
        vtype.set("probability", f"{share:.3f}")
        dist.append(vtype)
    return dist


def _heavy_types(rng: np.random.Generator) -> list[ET.Element]:
    """One truck and one bus type: slower, longer, gentler drivers."""
    truck = _vtype("truck", "truck", rng, accel=(0.9, 1.5), decel=(3.5, 4.5), tau=(1.2, 1.8), minGap=(2.0, 3.5))
    truck.set("length", f"{_draw(rng, 8.0, 14.0, 1):g}")
    bus = _vtype("bus", "bus", rng, accel=(1.0, 1.6), decel=(3.5, 4.5), tau=(1.1, 1.6), minGap=(2.0, 3.0))
    for vtype in (truck, bus):
        vtype.set("speedFactor", _speed_factor(rng, (0.85, 1.0), (0.03, 0.07)))
        vtype.attrib.update(_driver(rng, assertive=False))
    return [truck, bus]


def _bike_types(rng: np.random.Generator) -> ET.Element:
    """A distribution `bike` of 2 cyclist profiles."""
    dist = ET.Element("vTypeDistribution", id="bike")
    for i in range(2):
        vtype = _vtype(
            f"bike{i}", "bicycle", rng, accel=(0.8, 1.5), decel=(2.5, 3.5), tau=(0.8, 1.5), minGap=(0.5, 1.2)
        )
        vtype.set("desiredMaxSpeed", f"{_draw(rng, 4.0, 6.5):g}")
        vtype.set("speedFactor", _speed_factor(rng, (0.95, 1.05), (0.05, 0.12)))
        vtype.attrib.update(_driver(rng, assertive=False))
        vtype.set("probability", "0.5")
        dist.append(vtype)
    return dist


def _ped_types(rng: np.random.Generator) -> ET.Element:
    """A distribution `ped` of 2 pedestrian profiles (walking speed and its spread)."""
    dist = ET.Element("vTypeDistribution", id="ped")
    for i in range(2):
        vtype = ET.Element("vType", id=f"ped{i}", vClass="pedestrian", sigma="0", probability="0.5")
        vtype.set("desiredMaxSpeed", f"{_draw(rng, 1.1, 1.6):g}")
        vtype.set("speedFactor", _speed_factor(rng, (0.95, 1.05), (0.05, 0.12)))
        dist.append(vtype)
    return dist


def _vehicle_types(rng: np.random.Generator, network: BuiltNetwork, params: dict[str, object]) -> list[ET.Element]:
    """Every vType the demand uses; their drawn attributes are also recorded in `params`."""
    elements = [_car_types(rng), *_heavy_types(rng)]
    if network.bicycles:
        elements.append(_bike_types(rng))
    if network.pedestrians:
        elements.append(_ped_types(rng))
    types = {}
    for element in elements:
        for vtype in [element] if element.tag == "vType" else list(element):
            types[vtype.get("id")] = {k: v for k, v in vtype.attrib.items() if k != "id"}
    params["vtypes"] = types
    return elements


# --- flows ------------------------------------------------------------------------------------------


def _is_road(edge: sumolib.net.edge.Edge, vclass: str) -> bool:
    """A normal edge (not internal, crossing or walking area) that `vclass` may use."""
    return edge.getFunction() == "" and edge.allows(vclass)


def _normal_edges(net: sumolib.net.Net, vclass: str) -> list[sumolib.net.edge.Edge]:
    """Normal edges allowing `vclass`, sorted by id."""
    return sorted((e for e in net.getEdges(withInternal=False) if _is_road(e, vclass)), key=lambda e: e.getID())


def _linked(connections: Sequence[sumolib.net.connection.Connection], vclass: str) -> bool:
    """Whether any of `connections` joins two lanes that `vclass` may use."""
    return any(c.getFromLane().allows(vclass) and c.getToLane().allows(vclass) for c in connections)


def fringe_edges(net: sumolib.net.Net, vclass: str) -> tuple[list[str], list[str]]:
    """(sources, sinks): edges for `vclass` that no road leads into / that lead into no road (where
    traffic enters and leaves the network); every such edge when the network has no fringe."""
    edges = _normal_edges(net, vclass)
    sources, sinks = [], []
    for edge in edges:
        if not any(_is_road(e, vclass) and _linked(c, vclass) for e, c in edge.getIncoming().items()):
            sources.append(edge.getID())
        if not any(_is_road(e, vclass) and _linked(c, vclass) for e, c in edge.getOutgoing().items()):
            sinks.append(edge.getID())
    if not sources or not sinks:
        every = [e.getID() for e in edges]
        return every, every
    return sources, sinks


def _reachable(net: sumolib.net.Net, origin: str, destination: str, vclass: str) -> bool:
    """Whether `vclass` can drive from `origin` to `destination` without returning to where it came from.

    Cyclists must not turn left: from the rightmost (bike) lane a direct left turn cuts across the cars
    going straight on the same green, which SUMO resolves badly (junction collisions).
    """
    start, end = net.getEdge(origin), net.getEdge(destination)
    if origin == destination or end.getToNode() is start.getFromNode():
        return False
    path, _ = net.getShortestPath(start, end, vClass=vclass)
    if path is None:
        return False
    return vclass != "bicycle" or not _turns_left(path)


def _turns_left(path: Sequence[sumolib.net.edge.Edge]) -> bool:
    """Whether a route turns left (or makes a U-turn) anywhere along `path`."""
    for a, b in itertools.pairwise(path):
        if any(c.getDirection() in ("l", "L", "t") for c in a.getConnections(b)):
            return True
    return False


def _capacity(edge: sumolib.net.edge.Edge, vclass: str) -> float:
    """Lanes of `edge` open to `vclass` times its speed: how much traffic it can take."""
    return sum(1 for lane in edge.getLanes() if lane.allows(vclass)) * edge.getSpeed()


def _split(
    rng: np.random.Generator, net: sumolib.net.Net, origin: str, sinks: Sequence[str], vclass: str, rate: float
) -> list[tuple[str, float]]:
    """`rate` of `origin` split over its reachable sinks with Dirichlet-drawn destination weights whose
    means follow each sink's capacity (lanes x speed), so a side road or off-ramp draws less."""
    targets = [s for s in sinks if _reachable(net, origin, s, vclass)]
    if not targets:
        return []
    capacity = np.array([_capacity(net.getEdge(t), vclass) for t in targets])
    weights = rng.dirichlet(3.0 * len(targets) * capacity / capacity.sum())
    return [(t, rate * float(w)) for t, w in zip(targets, weights, strict=True)]


def _source_rates(
    net: sumolib.net.Net, rng: np.random.Generator, profile: DemandProfile, sources: Sequence[str]
) -> tuple[dict[str, float], dict[str, object]]:
    """Vehicles per hour entering at each source (per-lane rate x lanes ** exponent, minor roads scaled
    down, the total capped), and the values drawn for them."""
    minor_factor = _draw(rng, *profile.minor_factor)
    top_priority = max(net.getEdge(e).getPriority() for e in sources)
    rates = {}
    for origin in sources:
        edge = net.getEdge(origin)
        lanes = sum(1 for lane in edge.getLanes() if lane.allows("passenger"))  # not sidewalks, bike lanes
        per_lane = profile.highway_lane_rate if edge.getSpeed() >= HIGHWAY_SPEED else profile.lane_rate
        factor = 1.0 if edge.getPriority() >= top_priority else minor_factor
        rates[origin] = lanes**profile.lane_exponent * factor * _draw(rng, *per_lane, 1)
    drawn: dict[str, object] = {"minor_factor": minor_factor}
    if profile.max_total is not None:
        cap = _draw(rng, *profile.max_total, 1)
        drawn["max_total_vph"] = cap
        scale = min(1.0, cap / sum(rates.values()))
        rates = {k: v * scale for k, v in rates.items()}
    return {k: round(v, 1) for k, v in rates.items()}, drawn


def _vehicle_flows(
    net: sumolib.net.Net, rng: np.random.Generator, profile: DemandProfile, params: dict[str, object]
) -> list[_Flow]:
    """Car, truck and bus flows: a rate per source, split over the sinks it can reach."""
    sources, sinks = fringe_edges(net, "passenger")
    truck_share, bus_share = _draw(rng, *profile.truck_share, 3), _draw(rng, *profile.bus_share, 3)
    shares = {"car": 1.0 - truck_share - bus_share, "truck": truck_share, "bus": bus_share}
    source_rates, drawn = _source_rates(net, rng, profile, sources)
    flows = []
    for origin, rate in source_rates.items():
        for destination, pair_rate in _split(rng, net, origin, sinks, "passenger", rate):
            flows += [_Flow(t, origin, destination, pair_rate * share) for t, share in shares.items()]
    params.update(truck_share=truck_share, bus_share=bus_share, source_vph=source_rates, **drawn)
    params["vehicles_vph"] = round(sum(source_rates.values()), 1)
    return flows


def _bike_flows(
    net: sumolib.net.Net, rng: np.random.Generator, profile: DemandProfile, params: dict[str, object]
) -> list[_Flow]:
    """Cyclist flows between fringe edges reachable by bicycle; a drawn total rate split evenly."""
    sources, sinks = fringe_edges(net, "bicycle")
    total = _draw(rng, *profile.bike_rate, 1)
    params["bikes_vph"] = total
    flows = []
    for origin in sources:
        split = _split(rng, net, origin, sinks, "bicycle", total / len(sources))
        flows += [_Flow("bike", origin, destination, rate) for destination, rate in split]
    return flows


def _walk(net: sumolib.net.Net, origin: str, destination: str) -> tuple[int, float] | None:
    """(crossings walked over, length) of the shortest walk between two edges; None without a path."""
    path, cost = net.getShortestPath(
        net.getEdge(origin), net.getEdge(destination), vClass="pedestrian", withInternal=True, ignoreDirection=True
    )
    if path is None:
        return None
    return sum(1 for e in path if e.getFunction() == "crossing"), float(cost)


def _walk_pairs(net: sumolib.net.Net, rng: np.random.Generator) -> list[tuple[str, str]]:
    """Up to MAX_WALKS pairs of sidewalk edges, drawn at random, whose walk crosses a road and is at most
    MAX_WALK_M long (pedestrians start and end anywhere along a sidewalk, as if leaving a building)."""
    ends = [e.getID() for e in _normal_edges(net, "pedestrian")]
    candidates = [(a, b) for a in ends for b in ends if a != b]
    order = rng.permutation(len(candidates))[:MAX_WALK_TRIES]
    chosen = []
    for index in order:
        walk = _walk(net, *candidates[index])
        if walk is not None and walk[0] > 0 and walk[1] <= MAX_WALK_M:
            chosen.append(candidates[index])
            if len(chosen) == MAX_WALKS:
                break
    return sorted(chosen)


def _person_flows(
    net: sumolib.net.Net, rng: np.random.Generator, profile: DemandProfile, params: dict[str, object]
) -> list[_Flow]:
    """Pedestrian flows over drawn pairs of sidewalks that cross a road, with Dirichlet-drawn weights."""
    pairs = _walk_pairs(net, rng)
    total = _draw(rng, *profile.person_rate, 1)
    params["persons_ph"] = total
    params["walks"] = len(pairs)
    if not pairs:
        return []
    weights = rng.dirichlet(np.full(len(pairs), 2.0))
    return [_Flow("ped", a, b, total * float(w)) for (a, b), w in zip(pairs, weights, strict=True)]


# --- XML --------------------------------------------------------------------------------------------


def _period(rate_per_hour: float) -> str:
    """Poisson arrivals at `rate_per_hour` (SUMO's exponential period)."""
    return f"exp({rate_per_hour / 3600.0:.6g})"


def _flow_element(flow_id: str, flow: _Flow, duration_s: float) -> ET.Element:
    """A vehicle flow routed by SUMO at departure, inserted on the best lane at the desired speed."""
    return ET.Element(
        "flow",
        {
            "id": flow_id,
            "type": flow.type_id,
            "begin": "0",
            "end": f"{duration_s:.1f}",
            "period": _period(flow.rate),
            "from": flow.origin,
            "to": flow.destination,
            "departLane": "best",
            "departSpeed": "desired",
        },
    )


def _person_flow_element(flow_id: str, flow: _Flow, duration_s: float) -> ET.Element:
    """A pedestrian flow walking between random positions on two sidewalk edges."""
    element = ET.Element(
        "personFlow",
        {
            "id": flow_id,
            "type": flow.type_id,
            "begin": "0",
            "end": f"{duration_s:.1f}",
            "period": _period(flow.rate),
            "departPos": "random",
        },
    )
    ET.SubElement(element, "walk", {"from": flow.origin, "to": flow.destination, "arrivalPos": "random"})
    return element
