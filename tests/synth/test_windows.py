"""Window cutting and quality filters on hand-made tracks (no SUMO needed)."""

from __future__ import annotations

import numpy as np
import pytest

from langtraj.scenario.model import BehaviorEvent, RoadMap
from langtraj.scenario.types import AgentType, StateField
from langtraj.synth.network import InterestCentre
from langtraj.synth.tracks import Track
from langtraj.synth.windows import Rejection, RunData, SignalTable, WindowConfig, WindowCutter, boxes_overlap

NUM_STEPS = 400
CENTRE = InterestCentre(0.0, 0.0, 60.0, "junction", "C")
CONFIG = WindowConfig(warmup_s=5.0, stride_s=5.0, min_agents=10)


def _track(track_id: int, y: float, start: int = 0, stop: int = NUM_STEPS + 1, speed: float = 0.0) -> Track:
    n = stop - start
    x = -20.0 + speed * 0.1 * np.arange(n)
    return Track(
        track_id=track_id,
        sumo_id=f"v{track_id}",
        agent_type=AgentType.VEHICLE,
        vtype="car",
        size=(4.5, 1.8, 1.5),
        start=start,
        xy=np.stack([x, np.full(n, y)], axis=1),
        heading=np.zeros(n),
        speed=np.full(n, speed),
        valid=np.ones(n, bool),
        lane=np.zeros(n, np.int32),
        leader=np.full(n, -1),
        gap=np.full(n, np.nan, np.float32),
    )


def _run(tracks, events=(), collisions=(), teleports=()) -> RunData:
    signals = SignalTable(np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((NUM_STEPS + 1, 0), np.uint8))
    return RunData(tuple(tracks), tuple(events), NUM_STEPS, tuple(collisions), tuple(teleports), signals)


def _parked_row(count: int = 12):
    return [_track(i + 1, y=4.0 * i) for i in range(count)]  # side by side, 4 m apart: no overlap


YIELD = BehaviorEvent("yield", 3, 100, 140, 5, {"junction": "C"})
CHANGE = BehaviorEvent("lane_change", 4, 90, 130, -1, {"direction": "left", "change_step": 110})


def test_too_few_agents_is_rejected():
    cutter = WindowCutter(_run(_parked_row(5), [YIELD]), CONFIG)
    assert cutter.cut(CENTRE, 50) == Rejection("too_few_agents")


def test_window_without_interaction_is_rejected_unless_allowed():
    run = _run(_parked_row())
    assert WindowCutter(run, CONFIG).cut(CENTRE, 50) == Rejection("no_interaction")
    members, ooi, event = WindowCutter(run, WindowConfig(warmup_s=5.0, require_interaction=False)).cut(CENTRE, 50)
    assert len(members) == 12 and len(ooi) == 0 and event is None


def test_interacting_pair_is_the_objects_of_interest_and_events_are_rebased():
    cutter = WindowCutter(_run(_parked_row(), [YIELD, CHANGE]), CONFIG)
    members, ooi, event = cutter.cut(CENTRE, 50)
    assert event is YIELD  # a yield outranks a lane change
    scenario = cutter.scenario(members, ooi, 50, "w", RoadMap(), {"kind": "test"})
    ids = scenario.agents.ids
    assert ids[scenario.agents.objects_of_interest].tolist() == [3, 5]
    assert scenario.agents.ids[scenario.sdc_index] == 3
    assert set(ids[scenario.agents.tracks_to_predict]) >= {3, 5}
    events = {e.kind: e for e in scenario.events}
    assert (events["yield"].start, events["yield"].end) == (50, 90)
    assert (events["lane_change"].start, events["lane_change"].end) == (40, 80)
    assert events["lane_change"].attributes["change_step"] == 60
    assert scenario.num_steps == 91 and scenario.current_index == 10
    assert scenario.metadata["kind"] == "test"


def test_clipped_events_are_marked():
    cutter = WindowCutter(_run(_parked_row(), [YIELD]), CONFIG)
    members, ooi, _ = cutter.cut(CENTRE, 110)
    scenario = cutter.scenario(members, ooi, 110, "w", RoadMap(), {})
    (event,) = scenario.events
    assert event.start == 0 and event.attributes["clipped_start"] is True


@pytest.mark.parametrize(("step", "rejected"), [(120, True), (30, False), (300, False)])
def test_collision_of_a_member_inside_the_window_rejects_it(step, rejected):
    cutter = WindowCutter(_run(_parked_row(), [YIELD], collisions=[(step, 7, 8)]), CONFIG)
    result = cutter.cut(CENTRE, 100)
    assert (result == Rejection("collision")) is rejected


def test_teleport_rejects_the_window():
    cutter = WindowCutter(_run(_parked_row(), [YIELD], teleports=[(150, 2)]), CONFIG)
    assert cutter.cut(CENTRE, 100) == Rejection("teleport")


def test_overlapping_boxes_reject_the_window():
    tracks = _parked_row()
    tracks[1] = _track(2, y=1.0)  # 1 m beside track 1: the boxes (1.8 m wide) overlap
    cutter = WindowCutter(_run(tracks, [YIELD]), CONFIG)
    members, ooi, _ = cutter.cut(CENTRE, 50)
    assert cutter.scenario(members, ooi, 50, "w", RoadMap(), {}) == Rejection("overlap")


def test_agents_far_from_the_centre_are_left_out_and_late_arrivals_kept():
    tracks = [*_parked_row(), _track(50, y=500.0), _track(51, y=-4.0, start=120, speed=0.0)]
    cutter = WindowCutter(_run(tracks, [YIELD]), CONFIG)
    members, ooi, _ = cutter.cut(CENTRE, 100)
    scenario = cutter.scenario(members, ooi, 100, "w", RoadMap(), {})
    assert 50 not in scenario.agents.ids
    late = scenario.agents.index_of(51)
    assert not scenario.agents.valid[late, :20].any() and scenario.agents.valid[late, 20:].all()


def test_boxes_overlap_separating_axes():
    def states(*boxes):
        s = np.zeros((len(boxes), 1, 9), np.float32)
        for i, (x, y, h) in enumerate(boxes):
            s[i, 0, [StateField.X, StateField.Y, StateField.HEADING]] = x, y, h
            s[i, 0, [StateField.LENGTH, StateField.WIDTH]] = 4.0, 2.0
        return s

    valid = np.ones((2, 1), bool)
    vehicles = np.array([AgentType.VEHICLE] * 2, np.int8)
    assert boxes_overlap(states((0, 0, 0), (3.5, 0, 0)), valid, vehicles, 0.05)
    assert not boxes_overlap(states((0, 0, 0), (4.0, 0, 0)), valid, vehicles, 0.05)  # bumpers touch
    assert not boxes_overlap(states((0, 0, 0), (3.05, 3.05, np.pi / 2)), valid, vehicles, 0.05)
    assert boxes_overlap(states((0, 0, 0), (2.5, 2.0, np.pi / 2)), valid, vehicles, 0.05)
    pedestrians = np.array([AgentType.PEDESTRIAN] * 2, np.int8)
    assert not boxes_overlap(states((0, 0, 0), (0.1, 0, 0)), valid, pedestrians, 0.05)


def test_interaction_barely_inside_the_window_does_not_count():
    late = BehaviorEvent("yield", 3, 135, 160, 5, {})  # 5 steps inside a window starting at 50
    cutter = WindowCutter(_run(_parked_row(), [late]), CONFIG)
    assert cutter.cut(CENTRE, 50) == Rejection("no_interaction")
    assert cutter.cut(CENTRE, 60)[2] is late
