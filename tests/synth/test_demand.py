"""Traffic demand: the route file parses, every vehicle type is IDM with sigma 0 and named by its class,
cyclists / pedestrians appear iff the network has bike lanes / sidewalks, flows join existing edges over
the whole duration, a seed fixes the file, and a short SUMO run of every kind fills the network."""

from __future__ import annotations

import itertools
import json
import xml.etree.ElementTree as ET

import numpy as np
import pytest
import sumolib

from langtraj.synth.demand import Demand, fringe_edges, write_demand
from langtraj.synth.network import BuiltNetwork, get_kind, kind_names
from langtraj.synth.sumo import simulation_options

DURATION_S = 600.0
SIM_S = 40.0
PREFIXES = {"passenger": "car", "truck": "truck", "bus": "bus", "bicycle": "bike", "pedestrian": "ped"}


@pytest.fixture(scope="module")
def demands(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[BuiltNetwork, Demand]]:
    """Every kind (seed 0) with its demand, written in one folder per kind."""
    out = {}
    for kind in kind_names():
        workdir = tmp_path_factory.mktemp(kind)
        rng = np.random.default_rng(0)
        network = get_kind(kind).build(rng, workdir)
        out[kind] = network, write_demand(network, rng, DURATION_S, workdir)
    return out


def _root(demand: Demand) -> ET.Element:
    return ET.parse(demand.route_file).getroot()


@pytest.mark.parametrize("kind", kind_names())
def test_vehicle_types_are_idm_without_imperfection_and_named_by_class(demands, kind):
    network, demand = demands[kind]
    root = _root(demand)
    vtypes = list(root.iter("vType"))
    assert vtypes
    for vtype in vtypes:
        vclass = vtype.get("vClass", "")
        assert vtype.get("sigma") == "0"
        assert vtype.get("id", "").startswith(PREFIXES[vclass])
        if vclass != "pedestrian":
            assert vtype.get("carFollowModel") == "IDM"
            assert vtype.get("speedFactor", "").startswith("normc(")
    for dist in root.iter("vTypeDistribution"):
        members = {PREFIXES[v.get("vClass", "")] for v in dist.iter("vType")}
        assert members == {dist.get("id")}
    classes = {v.get("vClass") for v in vtypes}
    assert {"passenger", "truck", "bus"} <= classes
    assert ("bicycle" in classes) == network.bicycles
    assert ("pedestrian" in classes) == network.pedestrians


@pytest.mark.parametrize("kind", kind_names())
def test_flows_join_existing_edges_for_the_whole_duration(demands, kind):
    network, demand = demands[kind]
    net = sumolib.net.readNet(str(network.net_file), withInternal=True, withPedestrianConnections=True)
    root = _root(demand)
    flows, persons = list(root.iter("flow")), list(root.iter("personFlow"))
    assert flows
    types = {f.get("type") for f in flows}
    assert {"car", "truck"} <= types and ("bike" in types) == network.bicycles
    assert bool(persons) == network.pedestrians
    sources, sinks = fringe_edges(net, "passenger")
    for flow in flows:
        assert flow.get("begin") == "0" and float(flow.get("end", 0)) == DURATION_S
        assert flow.get("period", "").startswith("exp(")
        assert flow.get("departLane") == "best"
        assert net.hasEdge(flow.get("from")) and net.hasEdge(flow.get("to"))
        if flow.get("type") != "bike":
            assert flow.get("from") in sources and flow.get("to") in sinks
    for person in persons:
        (walk,) = person.iter("walk")
        assert person.get("begin") == "0" and float(person.get("end", 0)) == DURATION_S
        assert net.getEdge(walk.get("from")).allows("pedestrian") and net.getEdge(walk.get("to")).allows("pedestrian")
    assert demand.params["flows"] == len(flows) and demand.params["person_flows"] == len(persons)
    json.dumps(dict(demand.params))


def test_onramp_demand_feeds_the_mainline_and_the_ramp(demands):
    _, demand = demands["onramp"]
    rates = demand.params["source_vph"]
    assert set(rates) == {"main_in", "ramp_in"}
    assert rates["main_in"] > 1000.0 and 150.0 <= rates["ramp_in"] <= 700.0


def test_cyclists_do_not_turn_left(demands):
    network, demand = demands["signalized"]
    net = sumolib.net.readNet(str(network.net_file))
    for flow in _root(demand).iter("flow"):
        if flow.get("type") == "bike":
            path, _ = net.getShortestPath(net.getEdge(flow.get("from")), net.getEdge(flow.get("to")), vClass="bicycle")
            directions = {c.getDirection() for a, b in itertools.pairwise(path) for c in a.getConnections(b)}
            assert not directions & {"l", "L", "t"}


@pytest.mark.parametrize("kind", ("signalized", "city"))
def test_same_seed_gives_the_same_route_file_in_any_folder(demands, kind, tmp_path):
    network, demand = demands[kind]
    rng = np.random.default_rng(0)
    again_net = get_kind(kind).build(rng, tmp_path)
    again = write_demand(again_net, rng, DURATION_S, tmp_path)
    assert again.route_file.read_bytes() == demand.route_file.read_bytes()
    assert again.params == demand.params
    other = write_demand(network, np.random.default_rng(1), DURATION_S, tmp_path / "other")
    assert other.route_file.read_bytes() != demand.route_file.read_bytes()


def _simulate(network: BuiltNetwork, demand: Demand) -> dict[str, int]:
    """Run SUMO for SIM_S seconds; counts of agents present at the end, departures and incidents."""
    import libsumo

    options = simulation_options(
        network.net_file, [demand.route_file], seed=0, end_s=SIM_S, additional_files=network.additional_files
    )
    libsumo.start(["sumo", *options])
    counts = {"departed": 0, "collisions": 0, "teleports": 0}
    try:
        while libsumo.simulation.getTime() < SIM_S - 1e-6:
            libsumo.simulationStep()
            counts["departed"] += libsumo.simulation.getDepartedNumber()
            counts["collisions"] += len(libsumo.simulation.getCollisions())
            counts["teleports"] += libsumo.simulation.getStartingTeleportNumber()
        ids = libsumo.vehicle.getIDList()
        counts["vehicles"] = len(ids)
        counts["bikes"] = sum(1 for v in ids if libsumo.vehicle.getVehicleClass(v) == "bicycle")
        counts["persons"] = len(libsumo.person.getIDList())
    finally:
        libsumo.close()
    return counts


@pytest.mark.parametrize("kind", kind_names())
def test_a_short_simulation_fills_the_network(demands, kind):
    network, demand = demands[kind]
    counts = _simulate(network, demand)
    assert counts["departed"] >= 5 and counts["vehicles"] >= 3
    assert counts["teleports"] == 0 and counts["collisions"] <= 1
    assert (counts["persons"] > 0) == network.pedestrians
