"""The model's view of a scene: scene frame, agents' history and future, padding, the map and batching."""

from __future__ import annotations

import math
from dataclasses import fields, replace

import numpy as np
import pytest
import torch
from scenario_builders import make_scenario

from langtraj.model.batch import AGENT_HISTORY_FEATURES, SceneBatch
from langtraj.model.config import SampleConfig
from langtraj.model.features import (
    AUGMENTATION_FIELDS,
    SAMPLE_ARRAYS,
    collate_scenes,
    features_key,
    map_coverage,
    scene_frame,
    scene_sample,
)
from langtraj.scenario import MapFeature, MapFeatureType, RoadMap, Scenario

SMALL = SampleConfig(max_agents=8, max_polylines=12, points_per_polyline=10)


def _moved(scenario: Scenario, dx: float, dy: float, angle: float) -> Scenario:
    """The scene rotated by `angle` about the world origin, then shifted by (dx, dy)."""
    c, s = math.cos(angle), math.sin(angle)
    rot = np.array([[c, -s], [s, c]])
    states = scenario.agents.states.astype(np.float64).copy()
    states[..., 0:2] = states[..., 0:2] @ rot.T + (dx, dy)
    states[..., 3] += angle
    states[..., 4:6] = states[..., 4:6] @ rot.T
    features = []
    for f in scenario.road_map.features:
        pts = f.points.copy()
        pts[:, :2] = pts[:, :2] @ rot.T + (dx, dy)
        features.append(replace(f, points=pts))
    agents = replace(scenario.agents, states=states.astype(np.float32))
    return replace(scenario, agents=agents, road_map=RoadMap(features))


# ---------------------------------------------------------------- the scene frame and tensors


def test_the_focal_agent_is_at_the_origin_heading_along_x():
    scene = _moved(make_scenario(6), 1200.0, -340.0, 2.5)
    origin = scene_frame(scene)
    assert origin[:2] == pytest.approx(tuple(scene.agents.xy[0, 10]), abs=1e-3)
    assert origin[2] == pytest.approx(2.5, abs=1e-6)
    sample = scene_sample(scene, SMALL)
    assert sample["agent_id"][0] == 7  # the SDC comes first among the agents here
    np.testing.assert_allclose(sample["current_state"][0, :3], 0.0, atol=1e-3)
    np.testing.assert_allclose(sample["agent_history"][0, -1, :4], [0, 0, 1, 0], atol=1e-3)
    np.testing.assert_allclose(sample["origin"], [*origin], rtol=1e-6)


def test_without_a_valid_sdc_the_first_prioritized_agent_is_the_focal_agent():
    scene = replace(make_scenario(6), sdc_index=-1)
    first = scene.agents.objects_of_interest[0]
    assert scene_frame(scene)[:2] == pytest.approx(tuple(scene.agents.xy[first, 10]), abs=1e-4)


def test_a_sample_is_the_same_wherever_the_scene_lies_in_the_world():
    scene = make_scenario(6)
    a = scene_sample(scene, SMALL)
    b = scene_sample(_moved(scene, -5000.0, 777.0, -1.9), SMALL)
    for key in ("agent_history", "current_state", "future", "map_points"):
        np.testing.assert_allclose(a[key], b[key], atol=2e-3, err_msg=key)
    for key in ("history_valid", "future_valid", "map_valid", "map_type", "agent_id"):
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)


def test_history_and_future_are_the_world_tracks_moved_rigidly():
    scene = _moved(make_scenario(6), 300.0, 50.0, 0.7)
    sample = scene_sample(scene, SMALL)
    ids = sample["agent_id"][sample["agent_valid"]]
    rows = [scene.agents.index_of(i) for i in ids]
    world_hist = scene.agents.xy[rows, 0:11].astype(np.float64)
    world_fut = scene.agents.xy[rows, 11:91].astype(np.float64)
    local_hist = sample["agent_history"][: len(rows), :, :2]
    local_fut = sample["future"][: len(rows), :, :2]
    world = np.concatenate([world_hist, world_fut], axis=1).reshape(-1, 2)
    valid = np.concatenate([sample["history_valid"][: len(rows)], sample["future_valid"][: len(rows)]], axis=1)
    local = np.concatenate([local_hist, local_fut], axis=1).reshape(-1, 2)
    keep = valid.reshape(-1)
    pick = np.flatnonzero(keep)[::37]
    d_world = np.linalg.norm(world[pick, None] - world[None, pick], axis=-1)
    d_local = np.linalg.norm(local[pick, None] - local[None, pick], axis=-1)
    np.testing.assert_allclose(d_local, d_world, atol=5e-3)
    heading = sample["future"][: len(rows), :, 2]
    assert (np.abs(heading) <= math.pi).all()
    np.testing.assert_allclose(heading[sample["future_valid"][: len(rows)]], 0.0, atol=1e-4)  # all drive along x


def test_shapes_padding_and_dtypes():
    scene = make_scenario(6)  # agent 2 (id 27) appears late: not valid at the current step
    sample = scene_sample(scene, SMALL)
    a, m, p = SMALL.max_agents, SMALL.max_polylines, SMALL.points_per_polyline
    assert sample["agent_history"].shape == (a, 11, AGENT_HISTORY_FEATURES)
    assert sample["future"].shape == (a, 80, 3) and sample["future_valid"].shape == (a, 80)
    assert sample["map_points"].shape == (m, p, 2) and sample["map_valid"].shape == (m, p)
    assert sample["agent_valid"].tolist() == [True] * 5 + [False] * 3
    assert 27 not in sample["agent_id"].tolist()
    assert sample["agent_id"][5:].tolist() == [-1] * 3 and sample["agent_type"][5:].tolist() == [0] * 3
    assert not sample["history_valid"][5:].any() and not sample["future_valid"][5:].any()
    assert (sample["agent_history"][~sample["history_valid"]] == 0).all()
    assert (sample["agent_history"][sample["history_valid"]][:, -1] == 1).all()
    np.testing.assert_allclose(sample["agent_size"][:5], [[4.5, 2.0]] * 5)
    # speeds: agent a drives at 2 + 3a m/s along x
    speeds = {int(i): s for i, s in zip(sample["agent_id"][:5], sample["current_state"][:5, 3], strict=True)}
    assert speeds[7] == pytest.approx(2.0) and speeds[17] == pytest.approx(5.0)


def test_the_origin_map_holds_nearby_pieces_nearest_first_resampled_evenly():
    sample = scene_sample(make_scenario(6), replace(SMALL, max_polylines=64, map_selection="origin"))
    valid, pts, types = sample["map_valid"], sample["map_points"], sample["map_type"]
    rows = valid.any(axis=1)
    assert (types[~rows] == 0).all() and not valid[~rows].any() and (pts[~rows] == 0).all()
    assert (types[rows] > 0).all()
    nearest = [np.linalg.norm(pts[r][valid[r]], axis=-1).min() for r in np.flatnonzero(rows)]
    assert nearest == sorted(nearest) and nearest[-1] <= SMALL.map_radius
    full = valid.all(axis=1)
    gaps = np.linalg.norm(np.diff(pts[full], axis=1), axis=-1)
    assert gaps.max() <= 2.0 + 1e-4
    straight = types[full] != int(MapFeatureType.CROSSWALK)  # a polygon's corners shorten the chords
    np.testing.assert_allclose(gaps[straight], gaps[straight][:, :1].repeat(gaps.shape[1], 1), atol=1e-3)
    single = valid.sum(axis=1) == 1
    assert set(types[single].tolist()) == {int(MapFeatureType.STOP_SIGN)}
    assert int(MapFeatureType.CROSSWALK) in types.tolist()


def test_map_radius_and_polyline_budget_are_respected():
    scene = make_scenario(3)
    far = MapFeature(999, MapFeatureType.LANE_SURFACE_STREET, [[5000, 0, 0], [5100, 0, 0]])
    scene = replace(scene, road_map=RoadMap((*scene.road_map.features, far)))
    few = replace(SMALL, max_polylines=3)
    sample = scene_sample(scene, few)
    assert sample["map_valid"].any(axis=1).all()  # three nearest kept
    wide = scene_sample(scene, replace(SMALL, max_polylines=500))
    assert np.abs(wide["map_points"]).max() < 1000.0  # the far lane (5 km away) is left out


def test_missing_velocities_are_estimated_from_positions():
    scene = make_scenario(4)
    states = scene.agents.states.copy()
    states[..., 4:6] = 0.0
    still = replace(scene, agents=replace(scene.agents, states=states))
    sample = scene_sample(still, SMALL)
    speeds = dict(zip(sample["agent_id"][:3].tolist(), sample["current_state"][:3, 3].tolist(), strict=True))
    assert speeds[7] == pytest.approx(2.0, abs=0.2) and speeds[17] == pytest.approx(5.0, abs=0.2)
    assert sample["agent_history"][0, -1, 4] == pytest.approx(2.0, abs=0.2)


def test_collate_makes_a_scene_batch_with_contract_dtypes():
    scene = make_scenario(6)
    samples = [scene_sample(scene, SMALL) for _ in range(3)]
    for sample in samples:
        sample["text"][:2] = ["the target agent yields", "the target agent goes first"]
        sample["interaction_labelled"] = np.bool_(True)
    batch = collate_scenes(samples)
    assert isinstance(batch, SceneBatch) and batch.batch_size == 3 and batch.num_agents == SMALL.max_agents
    for name in ("agent_history", "agent_size", "current_state", "future", "map_points", "origin"):
        assert getattr(batch, name).dtype == torch.float32, name
    for name in ("history_valid", "agent_valid", "future_valid", "map_valid", "interaction_labelled"):
        assert getattr(batch, name).dtype == torch.bool, name
    for name in ("agent_type", "map_type", "agent_id"):
        assert getattr(batch, name).dtype == torch.long, name
    assert batch.interaction_labelled.tolist() == [True] * 3
    assert batch.has_text.sum(dim=1).tolist() == [2, 2, 2]
    assert batch.scenario_id == ["toy"] * 3
    assert batch.map_points.shape == (3, SMALL.max_polylines, SMALL.points_per_polyline, 2)


# ---------------------------------------------------------------- map coverage


def _two_distant_agents() -> Scenario:
    """Agent 7 at the origin driving east at 2 m/s among 20 parallel decoy lanes; agent 17 300 m away,
    driving north at 10 m/s on a lane of its own."""
    scene = make_scenario(2)
    states = scene.agents.states.copy()
    t = scene.timestamps
    states[1, :, 0], states[1, :, 1], states[1, :, 3] = 300.0, 10.0 * (t - t[10]), math.pi / 2
    states[1, :, 4], states[1, :, 5] = 0.0, 10.0
    lane = np.stack([np.linspace(-50, 150, 41), np.zeros(41), np.zeros(41)], axis=1)
    decoys = [
        MapFeature(600 + k, MapFeatureType.LANE_SURFACE_STREET, lane + [0, 3.5 * k * (-1) ** k, 0])
        for k in range(1, 21)
    ]
    north = MapFeature(
        700,
        MapFeatureType.LANE_SURFACE_STREET,
        np.stack([np.full(46, 300.0), np.linspace(-50, 400, 46), np.zeros(46)], 1),
    )
    road = RoadMap((MapFeature(100, MapFeatureType.LANE_SURFACE_STREET, lane), *decoys, north))
    return replace(scene, agents=replace(scene.agents, states=states), road_map=road)


def test_the_agent_map_covers_every_agent_and_the_road_ahead_where_the_origin_crop_does_not():
    scene = _two_distant_agents()
    budget = replace(SMALL, max_polylines=16)
    for selection, covered in (("origin", [True, False]), ("agents", [True, True])):
        sample = scene_sample(scene, replace(budget, map_selection=selection))
        arrays = (sample["map_points"], sample["map_valid"], sample["map_type"])
        now = map_coverage(arrays, sample["current_state"][:2, :2], np.ones(2, bool))
        assert now.tolist() == covered, selection
    # the north lane is kept at least 50 m ahead of agent 17 (its 8 s at 10 m/s reach 80 m), before the
    # decoy lanes more than 21 m beside agent 7
    ox, oy, heading = scene_frame(scene)
    assert heading == 0.0
    pts = sample["map_points"][sample["map_valid"]] + (ox, oy)  # back to the world
    assert pts[np.abs(pts[:, 0] - 300.0) < 0.5, 1].max() >= 50.0
    assert np.abs(pts[np.abs(pts[:, 0] - 300.0) > 1.0, 1]).max() <= 21.0 + 0.5


def test_map_coverage_counts_lane_points_within_five_metres_of_valid_positions():
    points = np.zeros((2, 3, 2), np.float32)
    points[0] = [[0, 0], [2, 0], [4, 0]]
    points[1] = [[0, 50], [2, 50], [4, 50]]
    valid = np.ones((2, 3), bool)
    types = np.array([int(MapFeatureType.ROAD_EDGE_BOUNDARY), int(MapFeatureType.LANE_FREEWAY)])
    positions = np.array([[4.0, 4.9], [1.0, 46.0], [1.0, 44.0], [0.0, 0.0]])
    out = map_coverage((points, valid, types), positions, np.array([True, True, True, False]))
    assert out.tolist() == [False, True, False, False]  # edges are not lanes; invalid positions do not count


def test_simulation_sizes_samples_for_the_agents_it_drives():
    trained = SampleConfig(max_agents=24, max_polylines=48)
    assert (trained.for_agents(48).max_agents, trained.for_agents(48).max_polylines) == (48, 96)
    assert (trained.for_agents(10).max_agents, trained.for_agents(10).max_polylines) == (10, 48)
    assert trained.for_agents(50).max_polylines == 100 and trained.for_agents(50).history_dropout == 0.0


class _Reads:
    """A config that records which of its fields are read."""

    def __init__(self, config: SampleConfig) -> None:
        self._config, self.read = config, set()

    def __getattr__(self, name: str):
        self.read.add(name)
        return getattr(self._config, name)


AUGMENTATION_CHANGES = {
    "text": False,
    "text_dropout": 0.9,
    "history_dropout": 0.1,
    "heuristic_label_fraction": 1.0,
    "interaction_fraction": 0.0,
    "decision_first": True,
}
"""Another value for each augmentation-only field: a new one must be added here too, and pass below."""


def test_every_sample_setting_is_in_the_store_key_or_declared_augmentation_only():
    names = {f.name for f in fields(SampleConfig)}
    keyed = set(features_key(SMALL)) - {"version"}
    assert names >= AUGMENTATION_FIELDS and set(AUGMENTATION_CHANGES) == AUGMENTATION_FIELDS
    assert keyed == names - AUGMENTATION_FIELDS  # every other field is keyed
    scene = make_scenario(6)
    for selection in ("agents", "origin"):
        reads = _Reads(replace(SMALL, map_selection=selection))
        scene_sample(scene, reads)  # type: ignore[arg-type]
        assert reads.read <= keyed and not reads.read & AUGMENTATION_FIELDS, selection
    base = scene_sample(scene, SMALL)
    for name, value in AUGMENTATION_CHANGES.items():
        changed = replace(SMALL, **{name: value})
        assert getattr(changed, name) != getattr(SMALL, name) and features_key(changed) == features_key(SMALL)
        sample = scene_sample(scene, changed)
        assert all(np.array_equal(sample[a], base[a]) for a in SAMPLE_ARRAYS), name
