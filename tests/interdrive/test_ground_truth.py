"""The SUMO event -> interaction label mapping, pinned per event kind on tiny constructed scenes."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import pytest

from langtraj.interdrive.ground_truth import GroundTruthConfig, ground_truth_interactions
from langtraj.interdrive.labels import LabelSource
from langtraj.scenario import Agents, AgentType, BehaviorEvent, MapFeature, MapFeatureType, RoadMap, Scenario

T = 91
VEH, PED, CYC = AgentType.VEHICLE, AgentType.PEDESTRIAN, AgentType.CYCLIST


def straight(x0: float, y0: float, heading: float, speeds: Sequence[float] | float) -> np.ndarray:
    """[T, 4] x, y, heading, speed of an agent driving straight at per-step `speeds`."""
    v = np.broadcast_to(np.asarray(speeds, np.float64), (T,))
    s = np.concatenate([[0.0], np.cumsum(v[:-1] * 0.1)])
    return np.stack([x0 + s * np.cos(heading), y0 + s * np.sin(heading), np.full(T, heading), v], axis=1)


def scene(
    tracks: Mapping[int, tuple[AgentType, np.ndarray]],
    events: Sequence[BehaviorEvent] = (),
    *,
    kind: str = "priority",
    features: Sequence[MapFeature] = (),
) -> Scenario:
    """A scenario with tracks id -> (type, [T, 4] x, y, heading, speed), events and map features."""
    ids = sorted(tracks)
    states = np.zeros((len(ids), T, 9), np.float32)
    for n, i in enumerate(ids):
        agent_type, track = tracks[i]
        states[n, :, 0:2] = track[:, 0:2]
        states[n, :, 3] = track[:, 2]
        states[n, :, 4] = track[:, 3] * np.cos(track[:, 2])
        states[n, :, 5] = track[:, 3] * np.sin(track[:, 2])
        states[n, :, 6:9] = (0.5, 0.5, 1.7) if agent_type == PED else (4.5, 2.0, 1.6)
    return Scenario(
        scenario_id="constructed",
        timestamps=np.arange(T) * 0.1,
        current_index=10,
        sdc_index=0,
        agents=Agents(
            ids=np.array(ids),
            types=np.array([tracks[i][0] for i in ids], np.int8),
            states=states,
            valid=np.ones((len(ids), T), bool),
        ),
        road_map=RoadMap(tuple(features)),
        events=tuple(events),
        metadata={"kind": kind},
    )


def crosswalk(fid: int, x0: float, x1: float, y0: float, y1: float) -> MapFeature:
    return MapFeature(fid, MapFeatureType.CROSSWALK, [[x0, y0, 0], [x1, y0, 0], [x1, y1, 0], [x0, y1, 0]])


def triples(scenario: Scenario) -> list[tuple[int, int, str]]:
    return [(lab.track_id, lab.other_id, lab.subtype.id) for lab in ground_truth_interactions(scenario)]


def _two_cars(events: Sequence[BehaviorEvent], kind: str = "priority", speeds=(10.0, 10.0)) -> Scenario:
    return scene({1: (VEH, straight(0, 0, 0, speeds[0])), 2: (VEH, straight(20, 3.5, 0, speeds[1]))}, events, kind=kind)


def _lc(reason: str, **extra) -> BehaviorEvent:
    return BehaviorEvent("lane_change", 1, 20, 50, 2, {"reason": reason, "change_step": 35, **extra})


@pytest.mark.parametrize(
    ("reason", "subtype"),
    [
        ("strategic", "lane_change/for_turn_or_exit"),
        ("cooperative", "lane_change/with_lead_or_trail"),
        ("keepRight", "lane_change/with_lead_or_trail"),
        ("speedGain", "lane_change/avoiding_slower_traffic"),
    ],
)
def test_lane_change_reason_gives_subtype_with_the_target_lane_leader(reason, subtype):
    labels = ground_truth_interactions(_two_cars([_lc(reason)]))
    assert [(lab.track_id, lab.other_id, lab.subtype.id, lab.start, lab.end) for lab in labels] == [
        (1, 2, subtype, 20, 50)
    ]
    assert labels[0].source is LabelSource.GROUND_TRUTH


def test_lane_change_out_of_an_ending_lane_is_a_merge():
    ends = _lc("strategic", from_lane_ends=True)
    assert triples(_two_cars([ends], kind="priority")) == [(1, 2, "merging/lane_reduction")]
    assert triples(_two_cars([ends], kind="onramp")) == [(1, 2, "merging/standard")]
    accelerating = np.linspace(5.0, 20.0, T)
    assert triples(_two_cars([ends], kind="onramp", speeds=(accelerating, 10.0))) == [
        (1, 2, "merging/on_ramp_accelerating")
    ]
    waited = np.where(np.arange(T) < 34, 0.0, 3.0)
    assert triples(_two_cars([ends], kind="onramp", speeds=(waited, 10.0))) == [(1, 2, "merging/late")]


def test_speed_gain_change_that_passes_the_former_leader_is_an_overtake():
    tracks = {
        1: (VEH, straight(0, 0, 0, 15.0)),  # the overtaker, starts 20 m behind
        2: (VEH, straight(20, 0, 0, 8.0)),  # the slow former leader
        3: (VEH, straight(80, 3.5, 0, 15.0)),  # leader on the target lane
    }
    events = [
        BehaviorEvent("follow", 1, 0, 30, 2),
        BehaviorEvent("lane_change", 1, 20, 40, 3, {"reason": "speedGain", "direction": "left", "change_step": 30}),
        BehaviorEvent("lane_change", 1, 60, 75, -1, {"reason": "keepRight", "direction": "right", "change_step": 70}),
    ]
    got = triples(scene(tracks, events))
    assert (1, 2, "lane_change/for_overtaking") in got
    assert (1, 2, "overtaking/standard") in got
    assert not any(sub.startswith("lane_change/") and other != 2 for _, other, sub in got if _ == 1)
    fast = {1: (VEH, straight(0, 0, 0, 25.0)), 2: (VEH, straight(20, 0, 0, 12.0)), 3: tracks[3]}
    assert (1, 2, "overtaking/high_speed") in triples(scene(fast, events))


def test_follow_subtypes():
    follow = [BehaviorEvent("follow", 1, 10, 60, 2)]
    assert triples(_two_cars(follow)) == [(1, 2, "following/with_lead")]
    stopping = np.where(np.arange(T) < 40, 10.0, 0.0)
    assert triples(_two_cars(follow, speeds=(stopping, 0.0))) == [(1, 2, "following/stopping_behind_lead")]
    passing = [*follow, BehaviorEvent("junction_pass", 2, 40, 70, -1, {"junction": "C", "direction": "s"})]
    assert (1, 2, "following/stopping_behind_intersection") in triples(_two_cars(passing, speeds=(stopping, 5.0)))
    slow = np.where(np.arange(T) < 10, 15.0, 4.0)
    assert triples(_two_cars(follow, speeds=(slow, 4.0))) == [(1, 2, "following/slow_lead")]
    close = scene({1: (VEH, straight(0, 0, 0, 15.0)), 2: (VEH, straight(9, 0, 0, 15.0))}, follow)
    assert triples(close) == [(1, 2, "following/tailgating")]


def test_yield_gives_the_yield_and_the_reverse_passing():
    y = BehaviorEvent("yield", 1, 20, 40, 2, {"junction": "C"})
    assert triples(_two_cars([y])) == [(1, 2, "yielding/intersection"), (2, 1, "passing/intersection_with_yielding")]
    rb = BehaviorEvent("yield", 1, 20, 40, 2, {"junction": "C", "roundabout": True})
    assert triples(_two_cars([rb])) == [(1, 2, "yielding/roundabout"), (2, 1, "passing/roundabout")]
    assert triples(_two_cars([y], kind="roundabout"))[0][2] == "yielding/roundabout"  # older corpora
    merging = [y, BehaviorEvent("lane_change", 2, 30, 50, -1, {"reason": "strategic"})]
    assert (1, 2, "yielding/to_merging_or_lane_change") in triples(_two_cars(merging))
    cyclist = scene({1: (VEH, straight(0, 0, 0, 5.0)), 2: (CYC, straight(20, 3.5, 0, 5.0))}, [y])
    assert triples(cyclist) == [(1, 2, "yielding/intersection"), (2, 1, "passing/vru_crossing")]


def test_going_first_passes_the_foe_which_yields_only_when_it_brakes():
    go = BehaviorEvent("go_first", 1, 20, 50, 2, {"junction": "C", "roundabout": False})
    steady = _two_cars([go])
    assert triples(steady) == [(1, 2, "passing/intersection_with_yielding")]
    braking = np.where(np.arange(T) < 30, 10.0, 7.0)
    foe = scene({1: (VEH, straight(0, 0, 0, 10.0)), 2: (VEH, straight(20, 3.5, 0, braking))}, [go])
    assert triples(foe) == [(1, 2, "passing/intersection_with_yielding"), (2, 1, "yielding/intersection")]
    rb = BehaviorEvent("go_first", 1, 20, 50, 2, {"junction": "C", "roundabout": True})
    assert triples(_two_cars([rb])) == [(1, 2, "passing/roundabout")]


def test_yield_to_pedestrian_and_reverse():
    tracks = {1: (VEH, straight(0, 0, 0, 0.0)), 5: (PED, straight(10, -3, np.pi / 2, 1.2))}
    event = BehaviorEvent("yield_to_pedestrian", 1, 10, 40, 5, {"crosswalk": "c0"})
    assert triples(scene(tracks, [event])) == [(1, 5, "yielding/to_pedestrian"), (5, 1, "passing/vru_crossing")]


def test_waiting_pedestrian_yields_to_the_cars_over_its_crosswalk():
    stand = straight(30, -4.5, np.pi / 2, np.where(np.arange(T) < 50, 0.0, 1.2))
    tracks = {
        1: (VEH, straight(20, 0, 0, 3.0)),  # over the crosswalk (x 29..33) around steps 29..45
        2: (VEH, straight(-200, 0, 0, 10.0)),  # never reaches it
        5: (PED, stand),
    }
    wait = BehaviorEvent("ped_waiting", 5, 0, 50, -1, {"crosswalk": "c0"})
    s = scene(tracks, [wait], features=[crosswalk(900, 29, 33, -3.5, 3.5)])
    labels = ground_truth_interactions(s)
    got = [(lab.track_id, lab.other_id, lab.subtype.id) for lab in labels]
    assert got == [(5, 1, "yielding/pedestrian_to_vehicle"), (1, 5, "passing/pedestrian")]
    passing = labels[1]
    assert 26 <= passing.start <= 30 and 44 <= passing.end <= 48


def test_window_filter_and_missing_agents():
    past = BehaviorEvent("lane_change", 1, 0, 10, 2, {"reason": "strategic"})  # ends at current_index
    ghost = BehaviorEvent("yield", 1, 20, 40, 99, {"junction": "C"})  # the foe is not in the scene
    alone = BehaviorEvent("lane_change", 1, 5, 30, -1, {"reason": "strategic"})
    assert triples(_two_cars([past, ghost, alone])) == [(1, -1, "lane_change/for_turn_or_exit")]


def test_labels_need_a_second_of_the_current_and_future_steps():
    short = BehaviorEvent("yield", 1, 0, 19, 2, {"junction": "C"})  # 9 steps from current_index 10
    enough = BehaviorEvent("yield", 1, 0, 20, 2, {"junction": "C"})
    assert triples(_two_cars([short])) == []
    assert triples(_two_cars([enough]))[0] == (1, 2, "yielding/intersection")
    assert ground_truth_interactions(_two_cars([short]), GroundTruthConfig(min_window_s=0.5)) != ()


def test_labels_need_the_other_agent_valid_during_the_overlap():
    s = _two_cars([BehaviorEvent("yield", 1, 20, 40, 2, {"junction": "C"})])
    s.agents.valid[1, 10:] = False  # the foe leaves the scene at the current step: neither label is observable
    assert triples(s) == []


def test_lane_change_needs_its_switch_inside_the_window():
    late = BehaviorEvent("lane_change", 1, 70, 91, 2, {"reason": "strategic", "change_step": 95, "clipped_end": True})
    early = BehaviorEvent("lane_change", 1, 0, 30, 2, {"reason": "strategic", "change_step": -5, "clipped_start": True})
    inside = BehaviorEvent("lane_change", 1, 70, 91, 2, {"reason": "strategic", "change_step": 88, "clipped_end": True})
    assert triples(_two_cars([late, early])) == []
    assert triples(_two_cars([inside])) == [(1, 2, "lane_change/for_turn_or_exit")]


def test_follow_keeps_the_steps_with_the_leader_within_range():
    follow = [BehaviorEvent("follow", 1, 10, 91, 2)]
    near = scene({1: (VEH, straight(0, 0, 0, 10.0)), 2: (VEH, straight(40, 0, 0, 10.0))}, follow)
    assert [(lab.start, lab.end) for lab in ground_truth_interactions(near)] == [(10, 91)]
    # the leader pulls away: the bumper gap 35.5 + 0.5 m per step passes 60 m after step 49
    away = scene({1: (VEH, straight(0, 0, 0, 10.0)), 2: (VEH, straight(40, 0, 0, 15.0))}, follow)
    ((lab,),) = [ground_truth_interactions(away)]
    assert (lab.start, lab.end) == (10, 50)
    far = scene({1: (VEH, straight(0, 0, 0, 10.0)), 2: (VEH, straight(80, 0, 0, 10.0))}, follow)
    assert ground_truth_interactions(far) == ()


def test_output_is_sorted_and_deterministic():
    events = [
        BehaviorEvent("yield", 2, 30, 40, 1, {"junction": "C"}),
        BehaviorEvent("follow", 1, 10, 60, 2),
        BehaviorEvent("lane_change", 1, 20, 50, 2, {"reason": "strategic"}),
    ]
    a = ground_truth_interactions(_two_cars(events))
    b = ground_truth_interactions(_two_cars(list(reversed(events))))
    assert a == b
    assert [lab.start for lab in a] == sorted(lab.start for lab in a)


def test_config_thresholds_apply():
    follow = [BehaviorEvent("follow", 1, 10, 60, 2)]
    close = scene({1: (VEH, straight(0, 0, 0, 15.0)), 2: (VEH, straight(9, 0, 0, 15.0))}, follow)
    relaxed = GroundTruthConfig(tailgating_headway_s=0.1)
    assert ground_truth_interactions(close, relaxed)[0].subtype.id == "following/with_lead"
