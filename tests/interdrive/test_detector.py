"""Each detector rule on small constructed trajectories, the evaluation matcher, and both labelers on synth."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from langtraj.interdrive.detector import (
    INTERACTION_RULES,
    DetectorConfig,
    InteractionRule,
    SceneGeometry,
    braking_lead_runs,
    cut_in_runs,
    detect_interactions,
    following_runs,
    overtake_cut_in_runs,
    pair_rows,
    passing_runs,
    pull_out_runs,
    red_light_runs,
    tailgating_runs,
    yielding_runs,
)
from langtraj.interdrive.evaluation import TypeCounts, add_counts, macro_f1, match_interactions
from langtraj.interdrive.labels import InteractionLabel, LabelSource
from langtraj.interdrive.taxonomy import SUBTYPES_BY_ID, InteractionType
from langtraj.scenario import LaneNeighbor, MapFeature, MapFeatureType, Scenario, TrafficLights
from langtraj.scenario.types import StateField, TrafficLightState

from .test_ground_truth import CYC, PED, VEH, T, crosswalk, scene, straight


def pairs(labels, kind: str) -> set[tuple[int, int]]:
    return {(lab.track_id, lab.other_id) for lab in labels if lab.type.value == kind}


def test_every_interaction_type_has_a_registered_rule():
    names = set(INTERACTION_RULES.names())
    assert names == {"lane_change", "following", "yielding", "passing", "overtaking", "merging"}
    assert all(issubclass(cls, InteractionRule) for cls in INTERACTION_RULES.classes())


def test_follower_behind_leader():
    s = scene(
        {1: (VEH, straight(0, 0, 0, 10.0)), 2: (VEH, straight(20, 0, 0, 10.0)), 3: (VEH, straight(0, 8, 0, 10.0))}
    )
    labels = detect_interactions(s)
    assert pairs(labels, "following") == {(1, 2)}
    follow = next(lab for lab in labels if lab.type is InteractionType.FOLLOWING)
    assert follow.source is LabelSource.DETECTOR and follow.subtype.id == "following/with_lead"
    assert follow.end == T


def test_follower_stopping_behind_leader():
    stop = np.where(np.arange(T) < 30, 5.0, 0.0)
    s = scene({1: (VEH, straight(0, 0, 0, stop)), 2: (VEH, straight(20, 0, 0, 0.0))})
    (label,) = detect_interactions(s)
    assert (label.track_id, label.other_id, label.subtype.id) == (1, 2, "following/stopping_behind_lead")


def test_car_stops_for_a_crossing_car_at_an_x_junction():
    wait = np.where(np.arange(T) < 50, 0.0, 5.0)
    tracks = {
        1: (VEH, straight(-8, 0, 0, wait)),  # waits west of the junction, then goes east
        2: (VEH, straight(0, -40, np.pi / 2, 10.0)),  # crosses northbound, at the centre at step 40
    }
    labels = detect_interactions(scene(tracks))
    assert pairs(labels, "yielding") == {(1, 2)}
    assert pairs(labels, "passing") == {(2, 1)}
    y = next(lab for lab in labels if lab.type is InteractionType.YIELDING)
    assert y.subtype.id == "yielding/intersection" and y.start < 40 < y.end


def test_no_yield_when_the_crossing_car_comes_after():
    tracks = {1: (VEH, straight(-30, 0, 0, 10.0)), 2: (VEH, straight(0, -80, np.pi / 2, 10.0))}
    labels = detect_interactions(scene(tracks))
    assert not pairs(labels, "yielding") and not pairs(labels, "passing")


def test_pedestrian_crossing_in_front_of_a_waiting_car():
    tracks = {1: (VEH, straight(20, 0, 0, 0.0)), 5: (PED, straight(28, -5, np.pi / 2, 1.2))}
    labels = detect_interactions(scene(tracks, features=[crosswalk(900, 26, 30, -3.5, 3.5)]))
    assert pairs(labels, "yielding") == {(1, 5)}
    assert pairs(labels, "passing") == {(5, 1)}
    assert {lab.subtype.id for lab in labels} == {"yielding/to_pedestrian", "passing/vru_crossing"}


def test_pedestrian_waits_for_a_car_over_the_crosswalk():
    stand = straight(30, -4.5, np.pi / 2, np.where(np.arange(T) < 50, 0.0, 1.2))
    tracks = {1: (VEH, straight(20, 0, 0, 3.0)), 5: (PED, stand)}  # the car is on the crosswalk steps 29..45
    labels = detect_interactions(scene(tracks, features=[crosswalk(900, 29, 33, -3.5, 3.5)]))
    assert {(lab.track_id, lab.other_id, lab.subtype.id) for lab in labels} >= {
        (5, 1, "yielding/pedestrian_to_vehicle"),
        (1, 5, "passing/pedestrian"),
    }


def test_pedestrian_standing_at_a_crosswalk_to_the_end_of_the_window_waits():
    tracks = {1: (VEH, straight(20, 0, 0, 3.0)), 5: (PED, straight(30, -4.5, np.pi / 2, 0.0))}
    labels = detect_interactions(scene(tracks, features=[crosswalk(900, 29, 33, -3.5, 3.5)]))
    assert (5, 1, "yielding/pedestrian_to_vehicle") in {(lab.track_id, lab.other_id, lab.subtype.id) for lab in labels}
    far = {1: tracks[1], 5: (PED, straight(30, -12, np.pi / 2, 0.0))}  # 8.5 m from it: no crosswalk of its own
    assert not pairs(detect_interactions(scene(far, features=[crosswalk(900, 29, 33, -3.5, 3.5)])), "yielding")


def test_queued_car_follows_and_does_not_yield():
    wait = np.where(np.arange(T) < 50, 0.0, 5.0)
    tracks = {
        1: (VEH, straight(-8, 0, 0, wait)),  # first at the junction: yields
        3: (VEH, straight(-16, 0, 0, wait)),  # queued behind 1: follows 1, yields to nobody
        2: (VEH, straight(0, -40, np.pi / 2, 10.0)),  # crosses northbound
    }
    labels = detect_interactions(scene(tracks))
    assert pairs(labels, "yielding") == {(1, 2)}
    assert (3, 1) in pairs(labels, "following")


def test_no_yield_to_a_foe_that_waits_itself():
    wait = np.where(np.arange(T) < 60, 0.0, 5.0)
    tracks = {
        1: (VEH, straight(-8, 0, 0, np.where(np.arange(T) < 75, 0.0, 5.0))),  # waits, goes last
        2: (VEH, straight(0, -8, np.pi / 2, wait)),  # waits too, then crosses first: 1 waited for nobody moving
    }
    labels = detect_interactions(scene(tracks))
    y = [lab for lab in labels if lab.type is InteractionType.YIELDING]
    assert all(lab.start >= 55 for lab in y)  # only once 2 moves off does 1 wait for it


def _two_lanes() -> list[MapFeature]:
    xs = np.linspace(-50, 400, 901)
    right = np.stack([xs, np.zeros_like(xs), np.zeros_like(xs)], axis=1)
    n = len(xs) - 1
    return [
        MapFeature(100, MapFeatureType.LANE_SURFACE_STREET, right, left_neighbors=(LaneNeighbor(101, 0, n, 0, n),)),
        MapFeature(
            101,
            MapFeatureType.LANE_SURFACE_STREET,
            right + [0, 3.5, 0],
            right_neighbors=(LaneNeighbor(100, 0, n, 0, n),),
        ),
    ]


def test_overtake_of_a_slower_leader():
    fast = straight(0, 0, 0, 15.0)
    ramp = np.clip((np.arange(T) - 10) / 15.0, 0.0, 1.0)
    fast[:, 1] = 3.5 * (3 * ramp**2 - 2 * ramp**3)
    fast[:, 2] = np.arctan2(np.gradient(fast[:, 1]), np.gradient(fast[:, 0]))
    tracks = {1: (VEH, fast), 2: (VEH, straight(25, 0, 0, 8.0))}
    labels = detect_interactions(scene(tracks, features=_two_lanes()))
    got = {(lab.track_id, lab.other_id, lab.subtype.id) for lab in labels}
    assert (1, 2, "overtaking/standard") in got
    assert (1, 2, "lane_change/for_overtaking") in got


def test_lane_change_names_the_target_lane_leader():
    mover = straight(0, 0, 0, 10.0)
    ramp = np.clip((np.arange(T) - 10) / 15.0, 0.0, 1.0)
    mover[:, 1] = 3.5 * (3 * ramp**2 - 2 * ramp**3)
    tracks = {1: (VEH, mover), 2: (VEH, straight(30, 3.5, 0, 10.0))}
    labels = detect_interactions(scene(tracks, features=_two_lanes()))
    assert pairs(labels, "lane_change") == {(1, 2)}
    assert not pairs(labels, "overtaking")


def test_lane_change_leader_on_the_target_lane_far_ahead_and_not_the_one_left_behind():
    mover = straight(0, 0, 0, 10.0)
    ramp = np.clip((np.arange(T) - 10) / 15.0, 0.0, 1.0)
    mover[:, 1] = 3.5 * (3 * ramp**2 - 2 * ramp**3)
    tracks = {
        1: (VEH, mover),
        2: (VEH, straight(25, 0, 0, 10.0)),  # ahead on the lane left, same speed: no overtake
        3: (VEH, straight(110, 3.5, 0, 10.0)),  # 110 m ahead on the target lane
    }
    labels = detect_interactions(scene(tracks, features=_two_lanes()))
    assert pairs(labels, "lane_change") == {(1, 3)}


def test_a_lane_change_just_ahead_of_a_vehicle_in_the_target_lane_cuts_in_front_of_it():
    mover = straight(20, 0, 0, 10.0)
    ramp = np.clip((np.arange(T) - 10) / 15.0, 0.0, 1.0)
    mover[:, 1] = 3.5 * (3 * ramp**2 - 2 * ramp**3)
    tracks = {1: (VEH, mover), 2: (VEH, straight(8, 3.5, 0, 10.0)), 3: (VEH, straight(-60, 3.5, 0, 10.0))}
    labels = detect_interactions(scene(tracks, features=_two_lanes()))
    cut_ins = {(lab.track_id, lab.other_id) for lab in labels if lab.subtype.id == "lane_change/cut_in"}
    assert cut_ins == {(1, 2)}  # 2 is 7.5 m behind in the target lane; 3 is 75 m behind, beyond `cut_in_range`
    assert cut_in_runs(SceneGeometry(scene(tracks, features=_two_lanes()), (), DetectorConfig()), 0, 1)


def _red_light_scene(
    light: TrafficLightState, other_y0: float = -40.0, other_heading: float = np.pi / 2, other_x0: float = 1.75
) -> Scenario:
    runner = straight(-40, -1.75, 0, 10.0)  # past the stop point (x = -8) at about 3.2 s, 10 m/s throughout
    other = straight(other_x0, other_y0, other_heading, 8.0)  # northbound across its way, there at about 4.8 s
    states = np.full((T, 1), light, np.int8)
    lights = TrafficLights([101], states, np.ones((T, 1), bool), [[-8.0, -1.75, 0.0]])
    return replace(scene({1: (VEH, runner), 2: (VEH, other)}), traffic_lights=lights)


def test_passing_a_red_stop_line_and_then_crossing_another_agents_way_runs_the_red_light_across_it():
    labels = detect_interactions(_red_light_scene(TrafficLightState.STOP))
    runs = [lab for lab in labels if lab.subtype.id == "passing/red_light_running"]
    assert [(lab.track_id, lab.other_id) for lab in runs] == [(1, 2)]
    assert 30 <= runs[0].start <= 34  # from when it passes the stop line
    geometry = SceneGeometry(_red_light_scene(TrafficLightState.STOP), (), DetectorConfig())
    assert red_light_runs(geometry, 0, 1) and not red_light_runs(geometry, 1, 0)
    behind = _red_light_scene(TrafficLightState.STOP, -1.75, 0.0, -60.0)  # following it in its lane
    for quiet in (_red_light_scene(TrafficLightState.GO), _red_light_scene(TrafficLightState.STOP, 40.0), behind):
        # a green light; the other already past the crossing, driving away north; the other behind it in its lane
        assert not any(lab.subtype.id == "passing/red_light_running" for lab in detect_interactions(quiet))


def _pull_out_scene(other_y0: float = -50.0, sets_off: int = 20) -> Scenario:
    """Car 1 stands west of a map-less crossing (x = -12, heading east) until `sets_off`, then pulls out east at
    2.5 m/s^2 (up to 10 m/s); car 2 drives north at 8 m/s along x = 1.75 from `other_y0`."""
    t = np.arange(T) * 0.1
    pulls = np.clip(2.5 * (t - sets_off * 0.1), 0.0, 10.0)
    side = straight(-12, -1.75, 0, pulls)
    main = straight(1.75, other_y0, np.pi / 2, 8.0)
    return scene({1: (VEH, side), 2: (VEH, main)})


def test_a_car_pulling_out_from_standing_just_ahead_of_a_passing_car_pulls_out_in_front_of_it():
    labels = detect_interactions(_pull_out_scene())
    found = [lab for lab in labels if lab.subtype.id == "merging/pull_out"]
    assert [(lab.track_id, lab.other_id) for lab in found] == [(1, 2)]
    assert 20 <= found[0].start <= 32 < 50 <= found[0].end  # from setting off to past coming onto its line
    geometry = SceneGeometry(_pull_out_scene(), (), DetectorConfig())
    assert pull_out_runs(geometry, 0, 1) and not pull_out_runs(geometry, 1, 0)
    for quiet in (
        _pull_out_scene(other_y0=-20.0),  # the other has passed by the time it gets there: it crosses behind
        _pull_out_scene(other_y0=-110.0),  # the other is far off: no one to pull out in front of
        _pull_out_scene(other_y0=-20.0, sets_off=-40),  # at 10 m/s throughout: it crosses, it does not pull out
    ):
        assert not any(lab.subtype.id == "merging/pull_out" for lab in detect_interactions(quiet))


def test_a_lane_change_into_a_vehicle_still_beside_it_is_no_cut_in():
    mover = straight(10, 0, 0, 10.0)
    ramp = np.clip((np.arange(T) - 10) / 15.0, 0.0, 1.0)
    mover[:, 1] = 3.5 * (3 * ramp**2 - 2 * ramp**3)
    tracks = {1: (VEH, mover), 2: (VEH, straight(8, 3.5, 0, 10.0))}  # 2 m behind: bumpers overlap at the switch
    labels = detect_interactions(scene(tracks, features=_two_lanes()))
    assert not any(lab.subtype.id == "lane_change/cut_in" for lab in labels)  # side-swiped, not cut in on
    assert not cut_in_runs(SceneGeometry(scene(tracks, features=_two_lanes()), (), DetectorConfig()), 0, 1)


def test_a_cut_in_by_a_vehicle_that_was_behind_shortly_before_is_an_overtake_and_cut_in():
    mover = straight(0, 0, 0, 14.0)  # 10 m behind 2 at the start, 4 m/s faster: level at about 2.5 s
    ramp = np.clip((np.arange(T) - 55) / 15.0, 0.0, 1.0)
    mover[:, 1] = 3.5 * (3 * ramp**2 - 2 * ramp**3)  # into 2's lane from 5.5 s, about 13 m ahead of it
    tracks = {1: (VEH, mover), 2: (VEH, straight(10, 3.5, 0, 10.0))}
    labels = detect_interactions(scene(tracks, features=_two_lanes()))
    overtakes = [lab for lab in labels if lab.subtype.id == "overtaking/cut_in"]
    assert [(lab.track_id, lab.other_id) for lab in overtakes] == [(1, 2)]
    assert overtakes[0].start <= 25  # from when 1 was still behind 2
    assert {(lab.track_id, lab.other_id) for lab in labels if lab.subtype.id == "lane_change/cut_in"} == {(1, 2)}
    geometry = SceneGeometry(scene(tracks, features=_two_lanes()), (), DetectorConfig())
    assert overtake_cut_in_runs(geometry, 0, 1) and not overtake_cut_in_runs(geometry, 1, 0)
    ahead = straight(20, 0, 0, 10.0)  # the plain cut-in: ahead of 2 throughout
    ahead[:, 1] = mover[:, 1]
    plain = {1: (VEH, ahead), 2: (VEH, straight(8, 3.5, 0, 10.0))}
    assert not overtake_cut_in_runs(SceneGeometry(scene(plain, features=_two_lanes()), (), DetectorConfig()), 0, 1)


def _ramp_lanes() -> list[MapFeature]:
    """An acceleration lane 10 (ending at x 150, entered from ramp lane 9) beside main lane 11 (from 12, on to 13)."""

    def lane(fid, x0, x1, y, **kw):
        xs = np.linspace(x0, x1, int(2 * (x1 - x0)) + 1)
        return MapFeature(fid, MapFeatureType.LANE_FREEWAY, np.stack([xs, np.full_like(xs, y), 0 * xs], 1), **kw)

    n = 400
    return [
        lane(9, -100, -50, -3.5, exit_lanes=(10,)),
        lane(10, -50, 150, -3.5, entry_lanes=(9,), left_neighbors=(LaneNeighbor(11, 0, n, 0, n),)),
        lane(12, -100, -50, 0.0, exit_lanes=(11,)),
        lane(11, -50, 150, 0.0, entry_lanes=(12,), exit_lanes=(13,), right_neighbors=(LaneNeighbor(10, 0, n, 0, n),)),
        lane(13, 150, 400, 0.0, entry_lanes=(11,)),
    ]


def test_change_out_of_an_acceleration_lane_is_a_merge_far_from_its_end():
    mover = straight(-40, -3.5, 0, np.linspace(12.0, 20.0, T))
    ramp = np.clip((np.arange(T) - 20) / 20.0, 0.0, 1.0)
    mover[:, 1] = -3.5 + 3.5 * (3 * ramp**2 - 2 * ramp**3)  # switches near x -10, 160 m before the lane ends
    tracks = {1: (VEH, mover), 2: (VEH, straight(40, 0, 0, 20.0))}
    labels = detect_interactions(scene(tracks, features=_ramp_lanes()))
    assert pairs(labels, "merging") == {(1, 2)} and not pairs(labels, "lane_change")
    merge = next(lab for lab in labels if lab.type is InteractionType.MERGING)
    assert merge.subtype.id == "merging/on_ramp_accelerating"
    # the same move between two lanes that both go on (or both end, as at a map crop) is no merge
    both_end = [
        f if f.id != 11 else MapFeature(11, f.type, f.points, right_neighbors=f.right_neighbors) for f in _ramp_lanes()
    ]
    labels = detect_interactions(scene(tracks, features=[f for f in both_end if f.id != 13]))
    assert pairs(labels, "lane_change") == {(1, 2)} and not pairs(labels, "merging")


def test_roundabout_is_told_from_the_map():
    angles = np.linspace(0, 2 * np.pi, 9)
    ring = []
    for k in range(8):
        arc = np.linspace(angles[k], angles[k + 1], 20)
        pts = np.stack([20 * np.cos(arc), 20 * np.sin(arc), 0 * arc], 1)
        ring.append(MapFeature(200 + k, MapFeatureType.LANE_SURFACE_STREET, pts, exit_lanes=(200 + (k + 1) % 8,)))
    wait = np.where(np.arange(T) < 50, 0.0, 5.0)
    tracks = {1: (VEH, straight(-8, 0, 0, wait)), 2: (VEH, straight(0, -40, np.pi / 2, 10.0))}
    labels = detect_interactions(scene(tracks, kind="priority", features=ring))
    assert {lab.subtype.id for lab in labels if lab.type is InteractionType.YIELDING} == {"yielding/roundabout"}
    plain = detect_interactions(scene(tracks, kind="roundabout"))  # the window kind is not read
    assert {lab.subtype.id for lab in plain if lab.type is InteractionType.YIELDING} == {"yielding/intersection"}


def _lab(track: int, other: int, sub: str, start: int, end: int) -> InteractionLabel:
    return InteractionLabel(track, other, SUBTYPES_BY_ID[sub], LabelSource.DETECTOR, start, end)


def test_matcher_counts_per_type():
    truth = [
        _lab(1, 2, "following/with_lead", 0, 50),
        _lab(1, 2, "following/slow_lead", 60, 90),
        _lab(3, 4, "yielding/intersection", 10, 30),
        _lab(4, 3, "passing/intersection_with_yielding", 10, 30),
    ]
    predicted = [
        _lab(1, 2, "following/tailgating", 40, 70),  # matches one (type, not subtype, counts)
        _lab(1, 2, "following/with_lead", 45, 48),  # matches the other one? no: no overlap with 60..90
        _lab(4, 3, "yielding/intersection", 10, 30),  # wrong direction
        _lab(4, 3, "passing/roundabout", 29, 40),  # overlaps one step
    ]
    counts = match_interactions(predicted, truth)
    assert counts["following"] == TypeCounts(tp=1, fp=1, fn=1)
    assert counts["yielding"] == TypeCounts(tp=0, fp=1, fn=1)
    assert counts["passing"] == TypeCounts(tp=1, fp=0, fn=0)
    strict = match_interactions(predicted, truth, min_overlap_steps=2)
    assert strict["passing"] == TypeCounts(tp=0, fp=1, fn=1)
    assert counts["following"].precision == 0.5 and counts["following"].f1 == 0.5
    assert macro_f1(counts) == pytest.approx((0.5 + 0.0 + 1.0) / 3)
    assert add_counts(counts, counts)["following"] == TypeCounts(2, 2, 2)


def test_a_128_agent_scene_gives_ordered_pairs_of_its_own_agents():
    rng = np.random.default_rng(0)
    tracks = {}
    for i in range(128):
        heading = rng.choice([0.0, np.pi / 2, np.pi, -np.pi / 2])
        tracks[i + 1] = (VEH, straight(*rng.uniform(-150, 150, 2), heading, rng.uniform(0, 15)))
    s = scene(tracks, features=_two_lanes())
    labels = detect_interactions(s)
    assert labels == detect_interactions(s)  # deterministic
    for lab in labels:
        assert lab.track_id in tracks and lab.other_id in (-1, *tracks) and lab.track_id != lab.other_id
        assert s.current_index <= lab.end and lab.start < lab.end <= s.num_steps


@pytest.mark.slow
def test_both_labelers_on_a_tiny_synth_corpus(tmp_path):
    from langtraj.interdrive.ground_truth import ground_truth_interactions
    from langtraj.scenario.io import read_scenarios
    from langtraj.synth.factory import FactoryConfig, run_factory
    from langtraj.synth.shard import ShardConfig
    from langtraj.synth.windows import WindowConfig

    shard = ShardConfig(duration_s=100.0, window=WindowConfig(warmup_s=40.0))
    config = FactoryConfig(
        kinds=("priority",), windows=3, seed=7, out=tmp_path, workers=1, windows_per_shard=3, shard=shard
    )
    manifest = run_factory(config, progress=False)
    counts: dict[str, TypeCounts] = {}
    for entry in manifest["shards"]:
        for s in read_scenarios(tmp_path / entry["file"]):
            truth = ground_truth_interactions(s)
            assert truth and truth == ground_truth_interactions(s)
            assert all(lab.end > s.current_index for lab in truth)
            counts = add_counts(counts, match_interactions(detect_interactions(s), truth))
    assert counts["following"].tp > 0
    assert 0.0 < macro_f1(counts) <= 1.0


# ---------------------------------------------------------------- real-scene plausibility rules


def test_cars_parked_in_a_row_follow_no_one_but_a_queue_on_a_lane_does():
    kerb = {1: (VEH, straight(0, -6, 0, 0.0)), 2: (VEH, straight(7, -6, 0, 0.0)), 3: (VEH, straight(14, -6, 0, 0.0))}
    assert not pairs(detect_interactions(scene(kerb, features=_two_lanes())), "following")
    queue = {1: (VEH, straight(0, 0, 0, 0.0)), 2: (VEH, straight(7, 0, 0, 0.0))}  # standing on lane 100
    assert pairs(detect_interactions(scene(queue, features=_two_lanes())), "following") == {(1, 2)}


def test_following_subtype_reads_only_steps_where_both_are_valid():
    s = scene({1: (VEH, straight(0, 0, 0, 10.0)), 2: (VEH, straight(20, 0, 0, 10.0))})
    s.agents.valid[0, 40:42] = False  # a 2-step gap in the track, joined into one run: its zero speed is no stop
    s.agents.states[0, 40:42, StateField.VX : StateField.VY + 1] = 0.0
    subs = {lab.subtype.id for lab in detect_interactions(s) if lab.type is InteractionType.FOLLOWING}
    assert subs == {"following/with_lead"}


def _boundary_track(speed: float) -> np.ndarray:
    """A car on the line between lanes 100 and 101, its nearest lane flickering every 5 steps."""
    track = straight(0, 1.75, 0, speed)
    track[:, 1] += np.where((np.arange(T) // 5) % 2 == 0, -0.1, 0.1)
    return track


def test_flickering_nearest_lane_is_no_lane_change():
    for speed in (0.0, 10.0):  # standing all window, or driving along the lane boundary
        labels = detect_interactions(scene({1: (VEH, _boundary_track(speed))}, features=_two_lanes()))
        assert not pairs(labels, "lane_change") and not pairs(labels, "merging"), speed


def test_slow_sideways_creep_is_no_lane_change():
    creep = straight(0, 0, 0, 1.0)  # 1 m/s: below lane_change_min_speed
    creep[:, 1] = np.linspace(0.0, 3.5, T)
    assert not pairs(detect_interactions(scene({1: (VEH, creep)}, features=_two_lanes())), "lane_change")


def test_without_lane_connectivity_a_change_is_no_merge():
    mover = straight(0, 0, 0, 10.0)
    ramp = np.clip((np.arange(T) - 10) / 15.0, 0.0, 1.0)
    mover[:, 1] = 3.5 * (3 * ramp**2 - 2 * ramp**3)
    short = [f if f.id != 100 else MapFeature(100, f.type, f.points[:200], left_neighbors=()) for f in _two_lanes()]
    labels = detect_interactions(scene({1: (VEH, mover)}, features=short))  # lane 100 ends, but nothing is linked
    assert pairs(labels, "lane_change") == {(1, -1)} and not pairs(labels, "merging")


def test_no_yield_from_a_parked_car_nor_to_a_standing_one():
    tracks = {
        1: (VEH, straight(50, -6, np.pi / 2, 0.0)),  # parked off the lane, nose to the road
        2: (VEH, straight(0, 0, 0, 10.0)),  # drives past on lane 100, across its straight extension
    }
    labels = detect_interactions(scene(tracks, features=_two_lanes()))
    assert not pairs(labels, "yielding") and not pairs(labels, "passing")
    slow = np.where(np.arange(T) < 50, 1.0, 0.0)
    tracks = {1: (VEH, straight(-12, 0, 0, slow)), 2: (VEH, straight(0, -3, np.pi / 2, 0.0))}  # 2 stands all window
    labels = detect_interactions(scene(tracks))
    assert not pairs(labels, "yielding") and not pairs(labels, "passing")


def test_a_loop_around_a_block_is_no_roundabout():
    def corner(fid: int, cx: float, cy: float, a0: float, straight_from, nxt: int) -> MapFeature:
        arc = np.linspace(a0, a0 + np.pi / 2, 10)
        bend = np.stack([cx + 5 * np.cos(arc), cy + 5 * np.sin(arc)], 1)
        run = np.linspace(straight_from, bend[0], 20, endpoint=False)
        pts = np.concatenate([run, bend])
        return MapFeature(fid, MapFeatureType.LANE_SURFACE_STREET, np.c_[pts, 0 * pts[:, 0]], exit_lanes=(nxt,))

    # a 40 m x 20 m rounded rectangle (a parking aisle): four lanes, each a straight then a 90 degree bend
    loop = [
        corner(300, 15, -5, -np.pi / 2, (-15, -10), 301),
        corner(301, 15, 5, 0.0, (20, -5), 302),
        corner(302, -15, 5, np.pi / 2, (15, 10), 303),
        corner(303, -15, -5, np.pi, (-20, 5), 300),
    ]
    tracks = {1: (VEH, straight(-8, 0, 0, 0.0))}
    assert not SceneGeometry(scene(tracks, features=loop), (), DetectorConfig()).lanes.has_roundabout


def test_car_standing_all_window_far_before_the_junction_yields_along_its_lanes():
    xs = np.linspace(-60, -5, 111)
    approach = np.stack([xs, np.zeros_like(xs), np.zeros_like(xs)], axis=1)
    inner = np.stack([np.linspace(-5, 5, 21), np.zeros(21), np.zeros(21)], axis=1)
    lanes = [
        MapFeature(200, MapFeatureType.LANE_SURFACE_STREET, approach, exit_lanes=(201,)),
        MapFeature(201, MapFeatureType.LANE_SURFACE_STREET, inner, entry_lanes=(200,), interpolating=True),
    ]
    tracks = {
        1: (VEH, straight(-30, 0, 0, 0.0)),  # stands 30 m west of the junction all window: 15 m ahead is no conflict
        2: (VEH, straight(0, -40, np.pi / 2, 10.0)),  # crosses northbound, at the centre at step 40
    }
    on = DetectorConfig(continue_on_map=True)
    assert pairs(detect_interactions(scene(tracks), config=on), "yielding") == set()  # no map: straight extension
    labels = detect_interactions(scene(tracks, features=lanes), config=on)
    assert pairs(labels, "yielding") == {(1, 2)} and pairs(labels, "passing") == {(2, 1)}
    assert not pairs(detect_interactions(scene(tracks, features=lanes)), "yielding")  # off by default


# ---------------------------------------------------------------- one ordered pair at a time


def _busy_junction(seed: int, n: int = 24) -> Scenario:
    """`n` vehicles, cyclists and pedestrians on two crossing roads, each standing until a random step (some not at
    all), a car standing on the eastbound lane and one parked beside it, a crosswalk over each road, and a light
    over the eastbound approach (a lane into a signalled junction lane, and its stop point) showing red for the
    first 4.5 s."""
    rng = np.random.default_rng(seed)
    tracks = {}
    for i in range(n):
        kind = rng.choice([VEH, VEH, VEH, CYC, PED])
        heading = rng.choice([0.0, np.pi / 2, np.pi, -np.pi / 2])
        d = rng.uniform(8, 50)
        side = rng.choice([-1.75, 1.75]) if kind != PED else rng.choice([-6.0, 6.0])
        x0, y0 = -d * np.cos(heading) - side * np.sin(heading), -d * np.sin(heading) + side * np.cos(heading)
        v = 1.3 if kind == PED else rng.uniform(3, 12)
        go = rng.integers(0, 80)
        tracks[i + 1] = (kind, straight(x0, y0, heading, np.where((np.arange(T) >= go) | (rng.random() < 0.3), v, 0.0)))
    tracks[n + 1] = (VEH, straight(-30, -1.75, 0.0, 0.0))  # stands on the eastbound lane all window
    tracks[n + 2] = (VEH, straight(-30, -6.0, 0.0, 0.0))  # parked beside it
    approach = np.stack([np.linspace(-80, -8, 73), np.full(73, -1.75), np.zeros(73)], 1)
    inner = np.stack([np.linspace(-8, 8, 17), np.full(17, -1.75), np.zeros(17)], 1)
    features = [
        crosswalk(900, -10, 10, 8, 12),
        crosswalk(901, 8, 12, -10, 10),
        MapFeature(100, MapFeatureType.LANE_SURFACE_STREET, approach, exit_lanes=(101,)),
        MapFeature(101, MapFeatureType.LANE_SURFACE_STREET, inner, entry_lanes=(100,), interpolating=True),
    ]
    s = scene(tracks, features=features)
    states = np.where(np.arange(T) < 45, TrafficLightState.STOP, TrafficLightState.GO).astype(np.int8)[:, None]
    lights = TrafficLights([101], states, np.ones((T, 1), bool), [[-8.0, -1.75, 0.0]])
    return replace(s, traffic_lights=lights)


def _detector_scenes() -> list[Scenario]:
    wait = np.where(np.arange(T) < 50, 0.0, 5.0)
    queue = {
        1: (VEH, straight(-8, 0, 0, wait)),
        3: (VEH, straight(-16, 0, 0, wait)),
        2: (VEH, straight(0, -40, np.pi / 2, 10.0)),
    }
    walks = {1: (VEH, straight(20, 0, 0, 0.0)), 5: (PED, straight(28, -5, np.pi / 2, 1.2))}
    stand = straight(30, -4.5, np.pi / 2, np.where(np.arange(T) < 50, 0.0, 1.2))
    waits = {1: (VEH, straight(20, 0, 0, 3.0)), 5: (PED, stand), 6: (PED, straight(31, 4.5, -np.pi / 2, 0.0))}
    return [
        scene(queue),
        scene(walks, features=[crosswalk(900, 26, 30, -3.5, 3.5)]),
        scene(waits, features=[crosswalk(900, 29, 33, -3.5, 3.5)]),
        *(_busy_junction(seed) for seed in range(2)),
    ]


PER_PAIR = {
    "yielding": yielding_runs, "passing": passing_runs, "following": following_runs, "red_light": red_light_runs,
    "braking_lead": braking_lead_runs, "pull_out": pull_out_runs,
}  # fmt: skip
OWN_RULE = {
    "passing/red_light_running": "red_light", "passing/braking_lead": "braking_lead", "merging/pull_out": "pull_out",
}  # fmt: skip
"""Subtypes judged by a per-pair rule of their own, not by their type's."""


@pytest.mark.parametrize("index", range(5))
def test_one_pair_judged_alone_gets_the_runs_of_the_whole_scene(index):
    s = _detector_scenes()[index]
    config = DetectorConfig()
    expected: dict[tuple[int, int, str], list[tuple[int, int]]] = {}
    for lab in detect_interactions(s, config=config):
        kind = OWN_RULE.get(lab.subtype.id, lab.type.value)
        expected.setdefault((lab.track_id, lab.other_id, kind), []).append((lab.start, lab.end))
    assert {kind for *_, kind in expected} & set(PER_PAIR)
    ids = s.agents.ids
    whole = SceneGeometry(s, (), config)
    xy, valid, types = s.agents.xy.astype(np.float64), s.agents.valid, s.agents.types
    for a in range(s.num_agents):
        for b in range(s.num_agents):
            if a == b:
                continue
            want = {kind: sorted(expected.get((int(ids[a]), int(ids[b]), kind), [])) for kind in PER_PAIR}
            got = {kind: sorted((p.start, p.end) for p in rule(whole, a, b)) for kind, rule in PER_PAIR.items()}
            assert got == want, (a, b)
            rows = pair_rows(xy, valid, types, a, b, config)  # a fresh scene of just the agents the rules read
            agents = replace(
                s.agents, ids=ids[rows], types=types[rows], states=s.agents.states[rows], valid=valid[rows]
            )
            cut = SceneGeometry(replace(s, agents=agents, sdc_index=-1), (), config)
            at = {int(r): k for k, r in enumerate(rows)}
            alone = {kind: sorted((p.start, p.end) for p in rule(cut, at[a], at[b])) for kind, rule in PER_PAIR.items()}
            assert alone == want, (a, b)


def test_per_agent_quantities_equal_those_of_every_agent_at_once():
    s = _busy_junction(0)
    steps = np.arange(0, T, 3)
    whole, alone = SceneGeometry(s, (), DetectorConfig()), SceneGeometry(s, (), DetectorConfig())
    assert whole.yields.red.any() and whole.static.sum() == 2 and whole.parked.sum() == 1
    for a in range(s.num_agents):
        fresh = SceneGeometry(s, (), DetectorConfig())
        np.testing.assert_array_equal(fresh.yields.held_of(a), whole.yields.held[a])
        np.testing.assert_array_equal(fresh.yields.red_of(a), whole.yields.red[a])
        np.testing.assert_array_equal(fresh.lanes.lanes_at(a, steps), whole.lanes.per_step[a, steps])
        np.testing.assert_array_equal(fresh.paths.leaders_at(a, steps), whole.paths.leaders[a, steps])
        np.testing.assert_array_equal(alone.paths.leaders_of(a), whole.paths.leaders[a])
        assert fresh.arrays.is_parked(a) == whole.parked[a] and fresh.arrays.is_static(a) == whole.static[a]


def test_a_lead_braking_hard_in_front_of_its_follower_is_a_braking_lead():
    steps = np.arange(T)
    braking = np.where(steps < 30, 12.0, np.maximum(12.0 - 5.0 * (steps - 30) * 0.1, 0.0))  # 5 m/s^2 from 3 s
    gentle = np.where(steps < 30, 12.0, np.maximum(12.0 - 1.0 * (steps - 30) * 0.1, 0.0))  # 1 m/s^2
    follower = np.where(steps < 30, 12.0, np.maximum(12.0 - 4.0 * (steps - 32) * 0.1, 0.0).clip(max=12.0))
    hard = {1: (VEH, straight(40, 0, 0, braking)), 2: (VEH, straight(0, 0, 0, follower))}
    labels = detect_interactions(scene(hard))
    leads = [lab for lab in labels if lab.subtype.id == "passing/braking_lead"]
    assert [(lab.track_id, lab.other_id) for lab in leads] == [(1, 2)]
    assert 28 <= leads[0].start <= 31  # from when the braking starts
    geometry = SceneGeometry(scene(hard), (), DetectorConfig())
    assert braking_lead_runs(geometry, 0, 1) and not braking_lead_runs(geometry, 1, 0)
    soft = {1: (VEH, straight(40, 0, 0, gentle)), 2: (VEH, straight(0, 0, 0, follower))}
    assert not any(lab.subtype.id == "passing/braking_lead" for lab in detect_interactions(scene(soft)))
    alone = {1: (VEH, straight(40, 0, 0, braking)), 2: (VEH, straight(0, 8, 0, 12.0))}  # 2 in another lane
    assert not any(lab.subtype.id == "passing/braking_lead" for lab in detect_interactions(scene(alone)))


def test_tailgating_runs_are_the_tailgating_labels_of_the_pair():
    close = {1: (VEH, straight(0, 0, 0, 12.0)), 2: (VEH, straight(9, 0, 0, 12.0))}  # 4.5 m at 12 m/s: 0.4 s
    far = {1: (VEH, straight(0, 0, 0, 12.0)), 2: (VEH, straight(25, 0, 0, 12.0))}  # 1.7 s
    for tracks, tailgating in ((close, True), (far, False)):
        labels = detect_interactions(scene(tracks))
        assert any(lab.subtype.id == "following/tailgating" for lab in labels) is tailgating
        assert bool(tailgating_runs(SceneGeometry(scene(tracks), (), DetectorConfig()), 0, 1)) is tailgating
