"""Drivers' decisions (`langtraj.synth.intents`): planning, the events they make, the `go_first` events, the
windows cut around them, and the controller on a small scripted SUMO network."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from langtraj.scenario.model import BehaviorEvent
from langtraj.scenario.types import AgentType
from langtraj.synth.events import NetContext, go_first_events
from langtraj.synth.intents import (
    AppliedDecision,
    Decision,
    IntentConfig,
    decision_events,
    plan_driver,
)
from langtraj.synth.network import InterestCentre
from langtraj.synth.runner import FoeObservation, LaneChangeRecord, SimulationInput, simulate
from langtraj.synth.sumo import run_tool
from langtraj.synth.tracks import Track, build_tracks
from langtraj.synth.windows import RunData, SignalTable, WindowConfig, WindowCutter


def _track(track_id: int, speed, lane=None, start: int = 0, x0: float = 0.0) -> Track:
    speed = np.asarray(speed, np.float64)
    n = len(speed)
    x = x0 + np.concatenate([[0.0], np.cumsum(speed[:-1]) * 0.1])
    return Track(
        track_id=track_id,
        sumo_id=f"v{track_id}",
        agent_type=AgentType.VEHICLE,
        vtype="car",
        size=(4.5, 1.8, 1.5),
        start=start,
        xy=np.stack([x, np.zeros(n)], axis=1),
        heading=np.zeros(n),
        speed=speed,
        valid=np.ones(n, bool),
        lane=np.zeros(n, np.int32) if lane is None else np.asarray(lane, np.int32),
        leader=np.full(n, -1),
        gap=np.full(n, np.nan, np.float32),
    )


# ---------------------------------------------------------------- planning


def test_a_driver_plan_depends_only_on_seed_and_id():
    config = IntentConfig()
    a = plan_driver("f1_car.3", 100, 7, config)
    b = plan_driver("f1_car.3", 100, 7, config)
    assert (a.timed, a.due, a.bold) == (b.timed, b.due, b.bold)
    assert a.rng.random() == b.rng.random()

    def plans(seed: int) -> list:
        return [(p.timed, p.due, p.bold) for p in (plan_driver(f"v{i}", 0, seed, config) for i in range(50))]

    assert plans(7) == plans(7) and plans(7) != plans(8)  # the seed changes them, the visiting order does not
    assert [plan_driver(f"v{i}", 0, 7, config).due for i in reversed(range(50))][::-1] == [p[1] for p in plans(7)]


def test_decision_shares_follow_the_config():
    config = IntentConfig(lane_change=0.2, pull_over=0.1, stop=0.0, speed_change=0.3, bold=0.25)
    plans = [plan_driver(f"f0_car.{i}", 50, 3, config) for i in range(4000)]
    counts = Counter(p.timed for p in plans)
    assert counts[Decision.STOP] == 0
    assert abs(counts[Decision.LANE_CHANGE] / 4000 - 0.2) < 0.03
    assert abs(counts[Decision.PULL_OVER] / 4000 - 0.1) < 0.03
    assert abs(counts[Decision.SPEED_CHANGE] / 4000 - 0.3) < 0.03
    assert abs(counts[None] / 4000 - 0.4) < 0.03
    assert abs(sum(p.bold for p in plans) / 4000 - 0.25) < 0.03
    lo, hi = config.delay_s
    dues = np.array([p.due for p in plans if p.timed is not None])
    assert dues.min() >= 50 + lo * 10 and dues.max() <= 50 + hi * 10


def test_config_rejects_shares_outside_zero_one_and_timed_shares_above_one():
    with pytest.raises(ValueError, match="shares"):
        IntentConfig(route_choice=1.5)
    with pytest.raises(ValueError, match="add up"):
        IntentConfig(lane_change=0.5, pull_over=0.3, stop=0.2, speed_change=0.2)


# ---------------------------------------------------------------- events of decisions


def test_route_choice_is_executed_when_the_vehicle_reaches_the_chosen_edge():
    lanes = ["SC_0", ":C_1_0", "CE_0", "CN_0"]
    lane = np.array([0] * 30 + [1] * 20 + [2] * 50)
    track = _track(1, np.full(100, 8.0), lane, start=200)
    reached = AppliedDecision(210, "v1", Decision.ROUTE_CHOICE, {"direction": "r", "next_edge": "CE"})
    missed = AppliedDecision(210, "v1", Decision.ROUTE_CHOICE, {"direction": "s", "next_edge": "CN"})
    (event,) = decision_events([reached], {"v1": track}, lanes, [])
    assert (event.kind, event.track_id, event.start, event.end) == ("decision", 1, 210, 251)
    assert event.attributes["executed"] and event.attributes["junction_exit_step"] == 250
    assert event.attributes["decision"] == "route_choice" and event.attributes["decision_step"] == 210
    (event,) = decision_events([missed], {"v1": track}, lanes, [])
    assert not event.attributes["executed"] and event.end == 211


def test_stop_spans_the_braking_and_the_standing_and_ends_when_moving_again():
    speed = np.concatenate([np.linspace(10, 0, 40), np.zeros(60), np.full(30, 3.0)])
    track = _track(2, speed)
    applied = AppliedDecision(5, "v2", Decision.PULL_OVER, {"duration_s": 6.0})
    (event,) = decision_events([applied], {"v2": track}, ["E_0"], [])
    stopped = int(np.flatnonzero(speed <= 0.3)[0])
    assert event.attributes["stopped_step"] == stopped and event.end == 100 and event.start == 5


def test_a_requested_lane_change_matches_only_a_traci_switch_after_the_decision():
    track = _track(3, np.full(120, 10.0))
    applied = AppliedDecision(20, "v3", Decision.LANE_CHANGE, {"direction": "left"})
    own = LaneChangeRecord("change", "v3", 45, "E_1", "E_2", 1, "traci|sublane")
    strategic = LaneChangeRecord("change", "v3", 30, "E_1", "E_2", 1, "strategic")
    early = LaneChangeRecord("change", "v3", 10, "E_0", "E_1", 1, "traci")
    (event,) = decision_events([applied], {"v3": track}, ["E_1"], [early, strategic, own])
    assert event.attributes["executed"] and event.attributes["change_step"] == 45 and event.end == 46
    (event,) = decision_events([applied], {"v3": track}, ["E_1"], [early, strategic])
    assert not event.attributes["executed"]


def test_bold_drivers_and_unknown_vehicles_make_no_decision_event():
    track = _track(4, np.full(50, 5.0))
    applied = [
        AppliedDecision(3, "v4", Decision.BOLD, {}),
        AppliedDecision(3, "ghost", Decision.SPEED_CHANGE, {}),
        AppliedDecision(3, "v4", Decision.SPEED_CHANGE, {"to_factor": 0.7}),
    ]
    events = decision_events(applied, {"v4": track}, ["E_0"], [])
    assert [e.attributes["decision"] for e in events] == ["speed_change"]


# ---------------------------------------------------------------- going first


CTX = NetContext({":C_0_0": "C"}, {}, frozenset())


def _obs(step, ego_dist, foe_dist, mutual=False):
    return FoeObservation(step, "v1", "v2", ":C_0_0", ":C_1_0", ego_dist, foe_dist, mutual)


@pytest.mark.parametrize(
    ("foe_dist", "foe_speed", "mutual", "expected"),
    [(20.0, 10.0, False, True), (60.0, 10.0, False, False), (20.0, 10.0, True, False), (-1.0, 10.0, False, False)],
)
def test_go_first_needs_a_priority_foe_within_the_horizon_still_before_the_conflict(
    foe_dist, foe_speed, mutual, expected
):
    tracks = {"v1": _track(1, np.full(200, 6.0)), "v2": _track(2, np.full(200, foe_speed))}
    observations = [_obs(90, 5.0, foe_dist + 10, mutual), _obs(100, -0.5, foe_dist, mutual)]
    events = go_first_events(observations, tracks, CTX, bold=frozenset({"v1"}))
    assert bool(events) == expected
    if expected:
        (event,) = events
        assert (event.kind, event.track_id, event.other_id, event.start, event.end) == ("go_first", 1, 2, 80, 110)
        assert event.attributes["gap_s"] == pytest.approx(foe_dist / foe_speed)
        assert event.attributes["bold"] and event.attributes["junction"] == "C"


# ---------------------------------------------------------------- windows around decisions


def test_windows_are_first_cut_so_that_a_decision_falls_after_the_current_step():
    tracks = [_track(i + 1, np.zeros(401)) for i in range(12)]
    decision = BehaviorEvent("decision", 3, 230, 260, -1, {"decision": "stop", "decision_step": 230, "executed": True})
    undone = BehaviorEvent("decision", 4, 300, 301, -1, {"decision": "stop", "decision_step": 300, "executed": False})
    signals = SignalTable(np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((401, 0), np.uint8))
    run = RunData(tuple(tracks), (decision, undone), 400, (), (), signals)
    config = WindowConfig(warmup_s=5.0, stride_s=5.0, min_agents=10)
    cutter = WindowCutter(run, config)
    candidates = list(cutter.candidates([InterestCentre(0.0, 0.0, 60.0, "junction", "C")]))
    lead = round(0.5 * sum(config.decision_lead_s) * 10)
    first = candidates[0]
    assert first == (0, 230 - lead - (config.history - 1))
    current = first[1] + config.history - 1
    assert 5 <= 230 - current <= 50
    assert candidates[1:] == [(0, s) for s in cutter.starts()]  # the undone decision gets no window


# ---------------------------------------------------------------- the controller in SUMO

NODES = """<nodes>
  <node id="W" x="-300" y="0"/><node id="E" x="150" y="0"/><node id="N" x="0" y="150"/>
  <node id="S" x="0" y="-150"/><node id="C" x="0" y="0" type="priority"/>
</nodes>"""

# A one-lane road W -> C whose lane leads left (N), straight (E) and right (S): a shared lane.
EDGES = """<edges>
  <edge id="WC" from="W" to="C" numLanes="1" speed="12.0" priority="3"/>
  <edge id="CE" from="C" to="E" numLanes="1" speed="12.0" priority="3"/>
  <edge id="CN" from="C" to="N" numLanes="1" speed="12.0" priority="1"/>
  <edge id="CS" from="C" to="S" numLanes="1" speed="12.0" priority="1"/>
</edges>"""

ROUTES = """<routes>
  <vType id="car" carFollowModel="IDM" sigma="0"/>
  <flow id="f" type="car" from="WC" to="CE" begin="0" end="60" period="6" departSpeed="10"/>
</routes>"""


@pytest.fixture(scope="module")
def junction_net(tmp_path_factory) -> Path:
    d: Path = tmp_path_factory.mktemp("intents")
    for name, text in (("n.nod.xml", NODES), ("n.edg.xml", EDGES), ("r.rou.xml", ROUTES)):
        (d / name).write_text(text)
    run_tool("netconvert", ["-n", "n.nod.xml", "-e", "n.edg.xml", "-o", "n.net.xml", "--no-turnarounds"], cwd=d)
    return d


def _simulate(d: Path, config: IntentConfig, seed: int = 1):
    sim = SimulationInput(
        d / "n.net.xml",
        (d / "r.rou.xml",),
        seed=seed,
        duration_s=90.0,
        intents=config,
        sinks={"passenger": ("CE", "CN", "CS")},
    )
    log = simulate(sim, d)
    tracks = {t.sumo_id: t for t in build_tracks(log.tracks)}
    return log, tracks


NO_TIMED = {"lane_change": 0.0, "pull_over": 0.0, "stop": 0.0, "speed_change": 0.0, "bold": 0.0}


def test_route_choices_spread_over_the_lane_directions_and_are_driven(junction_net):
    log, tracks = _simulate(junction_net, IntentConfig(route_choice=1.0, **NO_TIMED))
    choices = [d for d in log.decisions if d.decision == Decision.ROUTE_CHOICE]
    assert len(choices) >= 8  # every car of the flow decides on its approach
    assert {c.attributes["direction"] for c in choices} == {"l", "s", "r"}
    assert all(c.attributes["options"] == "lrs" and c.attributes["planned"] == "s" for c in choices)
    events = decision_events(log.decisions, tracks, log.lane_names, log.lane_changes)
    assert events and all(e.attributes["executed"] for e in events)
    for c in choices:  # each car left the junction on the edge it chose
        track = tracks[c.sumo_id]
        edges = {log.lane_names[i].rsplit("_", 1)[0] for i in track.lane[track.local(c.step) :] if i >= 0}
        assert c.attributes["next_edge"] in edges
        assert not ({"CE", "CN", "CS"} - {c.attributes["next_edge"]}) & edges
    assert not log.collisions and not log.teleports
    again, _ = _simulate(junction_net, IntentConfig(route_choice=1.0, **NO_TIMED))
    assert again.decisions == log.decisions  # deterministic in the seed


def test_pull_over_stops_at_the_kerb_side_of_the_lane(junction_net):
    config = IntentConfig(route_choice=0.0, **{**NO_TIMED, "pull_over": 1.0}, delay_s=(2.0, 4.0))
    log, tracks = _simulate(junction_net, config)
    events = decision_events(log.decisions, tracks, log.lane_names, log.lane_changes)
    pulls = [e for e in events if e.attributes["executed"]]
    assert pulls and all(e.attributes["decision"] == "pull_over" for e in events)
    first = min(pulls, key=lambda e: e.start)  # the first car has nobody stopped ahead of it
    track = next(t for t in tracks.values() if t.track_id == first.track_id)
    stopped, end = track.local(first.attributes["stopped_step"]), track.local(first.end)
    assert (track.speed[stopped:end] <= 0.3).all()
    assert (end - stopped) / 10 >= first.attributes["duration_s"] - 0.5
    # the road runs east along the lane centre the car drove on: standing, it moves to the right kerb
    assert track.xy[stopped:end, 1].min() < track.xy[0, 1] - 0.4


# A one-lane road with a zebra crossing over its east arm; one walker crosses it.
ZEBRA_NODES = """<nodes>
  <node id="W" x="-150" y="0"/><node id="E" x="150" y="0"/><node id="C" x="0" y="0" type="priority"/>
</nodes>"""
ZEBRA_EDGES = """<edges>
  <edge id="WC" from="W" to="C" numLanes="1" speed="12.0"/><edge id="CE" from="C" to="E" numLanes="1" speed="12.0"/>
  <edge id="EC" from="E" to="C" numLanes="1" speed="12.0"/><edge id="CW" from="C" to="W" numLanes="1" speed="12.0"/>
</edges>"""
ZEBRA_CONNECTIONS = """<connections><crossing node="C" edges="WC CW" priority="true"/></connections>"""
WALKER = """<routes>
  <person id="walker" depart="0" departPos="125"><walk edges="WC CW" arrivalPos="60"/></person>
</routes>"""


def test_a_waiting_pedestrian_stands_at_the_kerb_then_crosses(tmp_path):
    for name, text in (
        ("n.nod.xml", ZEBRA_NODES),
        ("n.edg.xml", ZEBRA_EDGES),
        ("n.con.xml", ZEBRA_CONNECTIONS),
        ("r.rou.xml", WALKER),
    ):
        (tmp_path / name).write_text(text)
    run_tool(
        "netconvert",
        ["-n", "n.nod.xml", "-e", "n.edg.xml", "-x", "n.con.xml", "-o", "n.net.xml", "--sidewalks.guess"]
        + ["--sidewalks.guess.min-speed", "0", "--no-turnarounds"],
        cwd=tmp_path,
    )
    config = IntentConfig(route_choice=0.0, **NO_TIMED, ped_wait=1.0, ped_wait_s=(5.0, 5.0))
    sim = SimulationInput(tmp_path / "n.net.xml", (tmp_path / "r.rou.xml",), seed=1, duration_s=150.0, intents=config)
    log = simulate(sim, tmp_path)
    tracks = {t.sumo_id: t for t in build_tracks(log.tracks)}
    waits = [d for d in log.decisions if d.decision == Decision.PED_WAIT]
    assert [d.sumo_id for d in waits] == ["walker"] and waits[0].attributes["duration_s"] == 5.0
    (event,) = decision_events(log.decisions, tracks, log.lane_names, log.lane_changes)
    assert event.attributes["executed"] and event.attributes["decision"] == "ped_wait"
    stood = (event.end - event.attributes["stopped_step"]) / 10
    assert 4.0 <= stood <= 6.5  # it stands about as long as it decided, then walks on over the crossing
    walker = tracks["walker"]
    assert walker.speed[walker.local(event.end) :].max() > 0.5
