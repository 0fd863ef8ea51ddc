"""Each detector rule on small constructed trajectories, the evaluation matcher, and both labelers on synth."""

from __future__ import annotations

import time

import numpy as np
import pytest

from langtraj.interdrive.detector import RULES, DetectorConfig, InteractionRule, detect_interactions
from langtraj.interdrive.evaluation import TypeCounts, add_counts, macro_f1, match_interactions
from langtraj.interdrive.labels import InteractionLabel, LabelSource
from langtraj.interdrive.taxonomy import SUBTYPES_BY_ID, InteractionType
from langtraj.scenario import LaneNeighbor, MapFeature, MapFeatureType

from .test_ground_truth import PED, VEH, T, crosswalk, scene, straight


def pairs(labels, kind: str) -> set[tuple[int, int]]:
    return {(lab.track_id, lab.other_id) for lab in labels if lab.type.value == kind}


def test_every_interaction_type_has_a_registered_rule():
    names = set(RULES.names())
    assert names == {"lane_change", "following", "yielding", "passing", "overtaking", "merging"}
    assert all(issubclass(cls, InteractionRule) for cls in RULES.classes())


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
    tracks = {1: (VEH, straight(0, 0, 0, 10.0)), 5: (PED, stand)}
    labels = detect_interactions(scene(tracks, features=[crosswalk(900, 29, 33, -3.5, 3.5)]))
    assert {(lab.track_id, lab.other_id, lab.subtype.id) for lab in labels} >= {
        (5, 1, "yielding/pedestrian_to_vehicle"),
        (1, 5, "passing/pedestrian"),
    }


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


def test_a_128_agent_scene_is_fast():
    rng = np.random.default_rng(0)
    tracks = {}
    for i in range(128):
        heading = rng.choice([0.0, np.pi / 2, np.pi, -np.pi / 2])
        tracks[i + 1] = (VEH, straight(*rng.uniform(-150, 150, 2), heading, rng.uniform(0, 15)))
    s = scene(tracks, features=_two_lanes())
    detect_interactions(s)
    began = time.perf_counter()
    detect_interactions(s, config=DetectorConfig())
    assert time.perf_counter() - began < 1.0


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
