"""Event extraction on a tiny scripted SUMO case: one forced lane change, one forced yield, one
pedestrian crossing (with a vehicle yielding to the pedestrian)."""

from __future__ import annotations

from pathlib import Path

import pytest

from langtraj.synth.events import extract_events
from langtraj.synth.mapping import build_net_map
from langtraj.synth.runner import SimulationInput, simulate
from langtraj.synth.shard import _net_context
from langtraj.synth.sumo import run_tool
from langtraj.synth.tracks import build_tracks

NODES = """<nodes>
  <node id="W" x="-200" y="0"/><node id="E" x="150" y="0"/><node id="S" x="0" y="-120"/>
  <node id="N" x="0" y="120"/><node id="C" x="0" y="0" type="priority"/>
</nodes>"""

# A one-way major road W -> E (2 lanes) crossed by a two-way minor road S - N.
EDGES = """<edges>
  <edge id="WC" from="W" to="C" numLanes="2" speed="13.0" priority="3"/>
  <edge id="CE" from="C" to="E" numLanes="2" speed="13.0" priority="3"/>
  <edge id="SC" from="S" to="C" numLanes="1" speed="10.0" priority="1"/>
  <edge id="CS" from="C" to="S" numLanes="1" speed="10.0" priority="1"/>
  <edge id="NC" from="N" to="C" numLanes="1" speed="10.0" priority="1"/>
  <edge id="CN" from="C" to="N" numLanes="1" speed="10.0" priority="1"/>
</edges>"""

# A zebra crossing (pedestrians have priority) over the north arm.
CONNECTIONS = """<connections><crossing node="C" edges="CN NC" priority="true"/></connections>"""

# `changer` starts in the right lane but turns left: a strategic lane change to the left. `merger`
# turns right from the minor road into a platoon on the major road: it must yield. `walker` crosses
# the north arm while `changer` turns into it.
ROUTES = """<routes>
  <vType id="car" carFollowModel="IDM" sigma="0" lcSpeedGain="0" lcKeepRight="0"/>
  <route id="left" edges="WC CN"/>
  <route id="straight" edges="WC CE"/>
  <route id="minor" edges="SC CE"/>
  <person id="walker" depart="0" departPos="105"><walk edges="NC CN"/></person>
  <vehicle id="changer" type="car" route="left" depart="0" departLane="1" departSpeed="8"/>
  <flow id="major" type="car" route="straight" begin="8" end="30" period="2.5" departLane="1" departSpeed="13"/>
  <vehicle id="merger" type="car" route="minor" depart="10" departPos="40" departSpeed="6"/>
</routes>"""


@pytest.fixture(scope="module")
def scripted(tmp_path_factory):
    d: Path = tmp_path_factory.mktemp("scripted")
    for name, text in (("n.nod.xml", NODES), ("n.edg.xml", EDGES), ("n.con.xml", CONNECTIONS), ("r.rou.xml", ROUTES)):
        (d / name).write_text(text)
    net = d / "n.net.xml"
    run_tool(
        "netconvert",
        ["-n", "n.nod.xml", "-e", "n.edg.xml", "-x", "n.con.xml", "-o", net.name, "--sidewalks.guess"]
        + ["--sidewalks.guess.min-speed", "0", "--no-turnarounds"],
        cwd=d,
    )
    net_map = build_net_map(net)
    log = simulate(SimulationInput(net, (d / "r.rou.xml",), seed=1, duration_s=60.0), d)
    tracks = build_tracks(log.tracks)
    events = extract_events(log, tracks, _net_context(net_map))
    names = {t.track_id: t.sumo_id for t in tracks}
    return log, tracks, events, names


def _of(events, kind, names, sumo_id):
    return [e for e in events if e.kind == kind and names[e.track_id] == sumo_id]


def test_forced_lane_change_is_strategic_to_the_left(scripted):
    log, tracks, events, names = scripted
    (change,) = _of(events, "lane_change", names, "changer")
    assert change.attributes["direction"] == "left"
    assert change.attributes["reason"] == "strategic"
    assert change.attributes["from_lane"] == "WC_1" and change.attributes["to_lane"] == "WC_2"
    assert change.start <= change.attributes["change_step"] < change.end
    assert change.end - change.start >= 10  # the sublane manoeuvre takes seconds, not one step
    changer = next(t for t in tracks if t.sumo_id == "changer")
    lanes = [log.lane_names[i] for i in changer.lane]
    assert lanes.index("WC_2") == change.attributes["change_step"] - changer.start


def test_forced_yield_names_a_major_road_foe_with_priority(scripted):
    _, tracks, events, names = scripted
    yields = _of(events, "yield", names, "merger")
    assert yields, "the merger must yield to the platoon"
    assert {names[e.other_id].split(".")[0] for e in yields} == {"major"}
    assert all(e.attributes["rule"] == "priority" and e.attributes["junction"] == "C" for e in yields)
    assert any(e.attributes["stopped"] for e in yields)
    merger = next(t for t in tracks if t.sumo_id == "merger")
    first = min(e.start for e in yields)
    assert merger.speed[first - merger.start] < 2.0 or merger.speed[first - merger.start + 1] < merger.speed[0]
    # nobody on the major road yields
    assert not [e for e in events if e.kind == "yield" and names[e.track_id].startswith("major")]


def test_pedestrian_crossing_and_a_vehicle_yielding_to_it(scripted):
    log, tracks, events, names = scripted
    (crossing,) = _of(events, "ped_crossing", names, "walker")
    assert crossing.attributes["crosswalk"] == ":C_c0"
    walker = next(t for t in tracks if t.sumo_id == "walker")
    on_crossing = [log.lane_names[i].startswith(":C_c0") for i in walker.lane]
    assert on_crossing.index(True) == crossing.start - walker.start
    assert sum(on_crossing) == crossing.end - crossing.start
    (ped_yield,) = _of(events, "yield_to_pedestrian", names, "changer")
    assert names[ped_yield.other_id] == "walker"
    assert crossing.start <= ped_yield.start < ped_yield.end <= crossing.end


def test_junction_passes_carry_the_link_direction_and_junction(scripted):
    log, tracks, events, names = scripted
    (changer,) = _of(events, "junction_pass", names, "changer")
    assert changer.attributes == {
        "junction": "C", "direction": "l", "control": "priority", "legs": 4, "intersection": True,
        "roundabout": False,
    }  # fmt: skip
    track = next(t for t in tracks if t.sumo_id == "changer")
    on_junction = [log.lane_names[i].startswith(":C_") for i in track.lane]
    assert on_junction.index(True) == changer.start - track.start
    assert sum(on_junction) == changer.end - changer.start
    merger = _of(events, "junction_pass", names, "merger")
    assert [e.attributes["direction"] for e in merger] == ["r"]
    platoon = [e for e in events if e.kind == "junction_pass" and names[e.track_id].startswith("major")]
    assert platoon and {e.attributes["direction"] for e in platoon} == {"s"}
    assert not _of(events, "junction_pass", names, "walker")  # pedestrians cross, they do not pass junctions


def test_lane_change_and_yield_flags_on_a_plain_junction(scripted):
    _, _, events, names = scripted
    (change,) = _of(events, "lane_change", names, "changer")
    assert change.attributes["from_lane_ends"] is False  # WC_1 goes on to CE
    assert all(e.attributes["roundabout"] is False for e in _of(events, "yield", names, "merger"))


def test_no_collisions_or_teleports_and_events_sorted(scripted):
    log, _, events, _ = scripted
    assert log.collisions == () and log.teleports == ()
    keys = [(e.start, e.track_id, e.kind, e.other_id, e.end) for e in events]
    assert keys == sorted(keys)


def test_waiting_at_a_red_light_is_not_being_held_back():
    import numpy as np

    from langtraj.scenario.types import AgentType
    from langtraj.synth.events import HeldSteps, NetContext
    from langtraj.synth.runner import SimulationLog
    from langtraj.synth.tracks import Track

    n = 30
    states = np.full((n + 1, 2), ord("r"), np.uint8)
    states[20:, 1] = ord("g")  # from step 20 one link of the lane turns (permissive) green
    log = SimulationLog((), ("A_0", "B_0"), n, states, (), (), (), ())
    ctx = NetContext({}, {}, frozenset(), {"A_0": (0, 1)})
    lane = np.zeros(n, np.int32)
    lane[25:] = 1  # on a lane without signals from step 26
    track = Track(1, "v", AgentType.VEHICLE, "car", (4.5, 1.8, 1.5), 1, np.zeros((n, 2)), np.zeros(n),
                  np.zeros(n), np.ones(n, bool), lane, np.full(n, -1), np.full(n, np.nan, np.float32))  # fmt: skip
    held = HeldSteps(log, ctx).of(track)
    assert not held[:19].any()  # standing at red
    assert held[19:].all()  # standing with a green to go on (yielding), or away from the signal
