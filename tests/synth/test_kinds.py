"""The built-in network kinds: every kind builds for several seeds, the net loads in sumolib, each kind
has its defining features (signals, stop signs, all-way stops, a priority crossing, a merge, a roundabout,
a random city with several junctions) and a seed gives byte-identical files in any folder."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET

import numpy as np
import pytest
import sumolib

from langtraj.synth.network import BuiltNetwork, get_kind, kind_names
from langtraj.synth.sumo import SynthError

KINDS = ("signalized", "priority", "allway", "roundabout", "onramp", "arterial", "zebra", "city")
SEEDS = (0, 1)
LABELS = {"junction", "merge", "crosswalk"}


@pytest.fixture(scope="module")
def built(tmp_path_factory: pytest.TempPathFactory) -> dict[tuple[str, int], BuiltNetwork]:
    """Every kind built for every seed, each in its own folder."""
    out = {}
    for kind in KINDS:
        for seed in SEEDS:
            workdir = tmp_path_factory.mktemp(f"{kind}{seed}")
            out[kind, seed] = get_kind(kind).build(np.random.default_rng(seed), workdir)
    return out


def _net(network: BuiltNetwork) -> sumolib.net.Net:
    return sumolib.net.readNet(str(network.net_file), withInternal=True, withPedestrianConnections=True)


def _states(network: BuiltNetwork) -> set[str]:
    """Link states of all vehicle connections in the net file."""
    root = ET.parse(network.net_file).getroot()
    return {c.get("state", "") for c in root.iter("connection") if c.get("via")}


def test_the_eight_kinds_are_registered_in_order():
    assert kind_names() == KINDS
    for name in KINDS:
        kind = get_kind(name)
        assert kind.name == name and kind.description and "\n" not in kind.description


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("kind", KINDS)
def test_every_kind_builds_a_loadable_net_with_centres(built, kind, seed):
    network = built[kind, seed]
    assert network.kind == kind and network.net_file.is_file()
    net = _net(network)
    xmin, ymin, xmax, ymax = net.getBoundary()
    assert max(xmax - xmin, ymax - ymin) < 1500.0, "networks stay compact"
    assert network.centres
    for centre in network.centres:
        assert centre.label in LABELS and 30.0 <= centre.radius <= 200.0
        assert xmin - 1 <= centre.x <= xmax + 1 and ymin - 1 <= centre.y <= ymax + 1
        if centre.junction_id:
            x, y = net.getNode(centre.junction_id).getCoord()[:2]
            if centre.label == "junction":
                assert (centre.x, centre.y) == pytest.approx((x, y), abs=0.01)
    json.dumps(dict(network.params))  # JSON-compatible
    edges = net.getEdges(withInternal=True)
    has_crossing = any(e.getFunction() == "crossing" for e in edges)
    has_sidewalk = any(lane.getPermissions() == {"pedestrian"} for e in edges for lane in e.getLanes())
    has_bike_lane = any(lane.getPermissions() == {"bicycle"} for e in edges for lane in e.getLanes())
    assert has_crossing == has_sidewalk == network.pedestrians
    assert has_bike_lane == network.bicycles


@pytest.mark.parametrize("seed", SEEDS)
def test_signalized_kinds_use_the_incoming_layout_with_all_red(built, seed):
    for kind in ("signalized", "arterial"):
        network = built[kind, seed]
        net = _net(network)
        assert net.getTrafficLights()
        root = ET.parse(network.net_file).getroot()
        for logic in root.iter("tlLogic"):
            phases = [(p.get("duration"), p.get("state", "")) for p in logic.iter("phase")]
            all_red = [d for d, state in phases if set(state) == {"r"}]
            assert all_red and all(d == "2" for d in all_red)
    assert len(_net(built["arterial", seed]).getTrafficLights()) == built["arterial", seed].params["junctions"]


@pytest.mark.parametrize("seed", SEEDS)
def test_priority_has_stop_signs_and_allway_has_allway_stops(built, seed):
    assert "s" in _states(built["priority", seed])
    assert "w" in _states(built["allway", seed])


@pytest.mark.parametrize("seed", SEEDS)
def test_zebra_crossing_gives_pedestrians_priority(built, seed):
    network = built["zebra", seed]
    root = ET.parse(network.net_file).getroot()
    crossings = [e.get("id") for e in root.iter("edge") if e.get("function") == "crossing"]
    assert len(crossings) == 1 and network.centres[0].label == "crosswalk"
    into_crossing = [c for c in root.iter("connection") if c.get("to") == crossings[0]]
    assert into_crossing and all(c.get("state") == "M" for c in into_crossing)
    vehicle_links = [c for c in root.iter("connection") if c.get("via", "").startswith(":M_")]
    assert vehicle_links and all(c.get("state") == "m" for c in vehicle_links)


@pytest.mark.parametrize("seed", SEEDS)
def test_onramp_has_an_acceleration_lane_that_ends(built, seed):
    network = built["onramp", seed]
    net = _net(network)
    lanes = network.params["lanes"]
    assert net.getEdge("main_in").getLaneNumber() == lanes
    accel = net.getEdge("accel")
    assert accel.getLaneNumber() == lanes + 1
    assert not accel.getLane(0).getOutgoing(), "the acceleration lane ends: ramp traffic must merge"
    assert network.centres[0].label == "merge" and network.centres[0].radius > 60.0


@pytest.mark.parametrize("seed", SEEDS)
def test_roundabout_is_a_roundabout(built, seed):
    network = built["roundabout", seed]
    (roundabout,) = _net(network).getRoundabouts()
    assert len(roundabout.getNodes()) == network.params["arms"]


@pytest.mark.parametrize("seed", SEEDS)
def test_city_has_several_junction_centres_of_mixed_types(built, seed):
    network = built["city", seed]
    assert 3 <= len(network.centres) <= 6
    net = _net(network)
    types = {net.getNode(c.junction_id).getType() for c in network.centres}
    assert len(set(network.params["junction_types"].values())) >= 2
    assert types <= {"traffic_light", "priority", "priority_stop", "allway_stop", "right_before_left"}


def test_seeds_draw_different_networks(built):
    for kind in KINDS:
        assert built[kind, 0].params != built[kind, 1].params, kind


@pytest.mark.parametrize("kind", KINDS)
def test_same_seed_gives_identical_files_in_any_folder(built, kind, tmp_path):
    again = get_kind(kind).build(np.random.default_rng(SEEDS[0]), tmp_path / "elsewhere")
    first = built[kind, SEEDS[0]]
    text = again.net_file.read_bytes()
    assert text == first.net_file.read_bytes()
    assert again.params == first.params and again.centres == first.centres
    assert str(tmp_path).encode() not in text and b"generated on" not in text
    assert sorted(p.name for p in tmp_path.joinpath("elsewhere").iterdir()) == sorted(
        p.name for p in first.net_file.parent.iterdir()
    )


def test_netconvert_errors_surface_as_synth_error(tmp_path):
    from langtraj.synth.kinds.xmlfiles import Edge, Node, PlainNetwork, build

    broken = PlainNetwork((Node("a", 0.0, 0.0),), (Edge("e", "a", "missing", 1, 10.0),))
    with pytest.raises(SynthError, match="netconvert"):
        build(broken, tmp_path, "broken")
