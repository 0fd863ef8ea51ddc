"""Training samples and batches: scene frame, padding, text selection, dropouts, dataset split and mixing."""

from __future__ import annotations

import math
import pickle
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch
from dataset_builders import make_prompt, make_record, write_dataset
from scenario_builders import make_scenario
from torch.utils.data import DataLoader

from langtraj.errors import InputError
from langtraj.model.batch import AGENT_HISTORY_FEATURES, SceneBatch
from langtraj.scenario import MapFeature, MapFeatureType, RoadMap, Scenario
from langtraj.training.data import (
    MixingSampler,
    SampleConfig,
    SceneDataset,
    build_sample,
    collate_scenes,
    scene_frame,
    split_of,
)

SMALL = SampleConfig(max_agents=8, max_polylines=12, points_per_polyline=10)
TEXT_ALWAYS = replace(SMALL, text_dropout=0.0, history_dropout=0.0)


def _rng(seed: int = 0) -> np.random.Generator:
    return np.random.default_rng(seed)


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
    sample = build_sample(scene, None, SMALL, _rng(), augment=False)
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
    a = build_sample(scene, None, SMALL, _rng(), augment=False)
    b = build_sample(_moved(scene, -5000.0, 777.0, -1.9), None, SMALL, _rng(), augment=False)
    for key in ("agent_history", "current_state", "future", "map_points"):
        np.testing.assert_allclose(a[key], b[key], atol=2e-3, err_msg=key)
    for key in ("history_valid", "future_valid", "map_valid", "map_type", "agent_id"):
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)


def test_history_and_future_are_the_world_tracks_moved_rigidly():
    scene = _moved(make_scenario(6), 300.0, 50.0, 0.7)
    sample = build_sample(scene, None, SMALL, _rng(), augment=False)
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
    sample = build_sample(scene, None, SMALL, _rng(), augment=False)
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


def test_the_map_holds_nearby_pieces_nearest_first_resampled_evenly():
    sample = build_sample(make_scenario(6), None, replace(SMALL, max_polylines=64), _rng(), augment=False)
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
    sample = build_sample(scene, None, few, _rng(), augment=False)
    assert sample["map_valid"].any(axis=1).all()  # three nearest kept
    wide = build_sample(scene, None, replace(SMALL, max_polylines=500), _rng(), augment=False)
    assert np.abs(wide["map_points"]).max() < 100.0  # the far lane is left out


def test_missing_velocities_are_estimated_from_positions():
    scene = make_scenario(4)
    states = scene.agents.states.copy()
    states[..., 4:6] = 0.0
    still = replace(scene, agents=replace(scene.agents, states=states))
    sample = build_sample(still, None, SMALL, _rng(), augment=False)
    speeds = dict(zip(sample["agent_id"][:3].tolist(), sample["current_state"][:3, 3].tolist(), strict=True))
    assert speeds[7] == pytest.approx(2.0, abs=0.2) and speeds[17] == pytest.approx(5.0, abs=0.2)
    assert sample["agent_history"][0, -1, 4] == pytest.approx(2.0, abs=0.2)


# ---------------------------------------------------------------- text


def test_stage_one_has_no_text():
    scene = make_scenario(6)
    record = make_record(scene, [make_prompt((7, 17), "yield/yield_to"), make_prompt((37,))])
    stage1 = replace(TEXT_ALWAYS, text=False)
    assert all(t is None for t in build_sample(scene, record, stage1, _rng())["text"])


def test_an_interaction_prompt_conditions_every_agent_it_mentions_plus_single_agent_sentences():
    """The paper's recipe: the interaction prompt's agents, and 30 % (at least one) of the other agents
    with single-agent labels, here one of tracks 7 and 37."""
    scene = make_scenario(6)
    interaction = make_prompt((17, 47), "yield/yield_to")
    singles = {7: make_prompt((7,)), 37: make_prompt((37,))}
    record = make_record(scene, [interaction, *singles.values()])
    seen = set()
    for seed in range(10):
        sample = build_sample(scene, record, TEXT_ALWAYS, _rng(seed))
        got = {int(i): t for i, t in zip(sample["agent_id"], sample["text"], strict=True) if t is not None}
        extra = set(got) - {17, 47}
        assert {k: got[k] for k in (17, 47)} == dict(interaction.roles)
        assert len(extra) == 1 and extra <= set(singles)
        (track,) = extra
        assert got[track] == singles[track].roles[track]
        seen |= extra
        assert bool(sample["interaction_labelled"])
    assert seen == set(singles)


def test_an_interaction_prompt_naming_an_agent_outside_the_sample_is_not_used():
    scene = make_scenario(6)  # track 27 is not valid at the current step
    record = make_record(scene, [make_prompt((17, 27), "yield/yield_to"), make_prompt((37,))])
    sample = build_sample(scene, record, TEXT_ALWAYS, _rng())
    got = {int(i): t for i, t in zip(sample["agent_id"], sample["text"], strict=True) if t is not None}
    assert got == {37: "the target agent label of 37"}  # falls back to the label sentences
    given = build_sample(scene, record, TEXT_ALWAYS, _rng(), prompt=make_prompt((17, 27), "yield/yield_to"))
    assert all(t is None for t in given["text"])


def test_a_given_prompt_overrides_the_pool():
    scene = make_scenario(6)
    record = make_record(scene, [make_prompt((17, 47), "yield/yield_to")])
    sample = build_sample(scene, record, TEXT_ALWAYS, _rng(), prompt=make_prompt((7,)))
    got = {int(i): t for i, t in zip(sample["agent_id"], sample["text"], strict=True) if t is not None}
    assert got == {7: "the target agent label of 7"}


def test_single_agent_sentences_go_to_a_fraction_of_the_labelled_agents():
    scene = make_scenario(12)
    valid_ids = [int(i) for i, v in zip(scene.agents.ids, scene.agents.valid[:, 10], strict=True) if v]
    assert len(valid_ids) == 11
    record = make_record(scene, [make_prompt((i,)) for i in valid_ids[:10]])
    config = replace(TEXT_ALWAYS, max_agents=16)
    picked: set[int] = set()
    for seed in range(20):
        sample = build_sample(scene, record, config, _rng(seed))
        got = {int(i): t for i, t in zip(sample["agent_id"], sample["text"], strict=True) if t is not None}
        assert len(got) == 3  # 30% of 10
        assert all(t == f"the target agent label of {i}" for i, t in got.items())
        picked |= set(got)
        assert not bool(sample["interaction_labelled"])
    assert len(picked) > 3  # a different share each time
    two = make_record(scene, [make_prompt((7,)), make_prompt((17,))])
    assert sum(t is not None for t in build_sample(scene, two, config, _rng())["text"]) == 1  # at least one


def test_text_dropout_removes_all_text_at_its_rate():
    scene = make_scenario(6)
    record = make_record(scene, [make_prompt((17, 47), "yield/yield_to")])
    config = replace(SMALL, text_dropout=0.5, history_dropout=0.0)
    empty = [all(t is None for t in build_sample(scene, record, config, _rng(s))["text"]) for s in range(400)]
    assert 0.4 < np.mean(empty) < 0.6
    no_augment = [build_sample(scene, record, config, _rng(s), augment=False)["text"] for s in range(20)]
    assert all(any(t is not None for t in text) for text in no_augment)


def test_history_dropout_keeps_only_the_current_step():
    scene = make_scenario(6)
    config = replace(SMALL, history_dropout=0.5, text_dropout=0.0)
    dropped = 0
    for seed in range(200):
        sample = build_sample(scene, None, config, _rng(seed))
        hv, agents = sample["history_valid"], sample["agent_valid"]
        if not hv[:, :-1].any():
            dropped += 1
            assert (sample["agent_history"][:, :-1] == 0).all()
            assert (hv[:, -1] == agents).all()
    assert 70 < dropped < 130
    kept = build_sample(scene, None, replace(config, history_dropout=1.0), _rng(), augment=False)
    assert kept["history_valid"][:, :-1].any()  # no dropout without augmentation


# ---------------------------------------------------------------- batches


def test_collate_makes_a_scene_batch_with_contract_dtypes():
    scene = make_scenario(6)
    record = make_record(scene, [make_prompt((17, 47), "yield/yield_to")])
    samples = [build_sample(scene, record, TEXT_ALWAYS, _rng(s)) for s in range(3)]
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


# ---------------------------------------------------------------- the dataset


@pytest.fixture(scope="module")
def labels_dir(tmp_path_factory) -> Path:
    return write_dataset(tmp_path_factory.mktemp("training"))


def test_split_is_fixed_by_scene_id_and_covers_every_window(labels_dir):
    every = SceneDataset(labels_dir, SMALL, split="all")
    train = SceneDataset(labels_dir, SMALL, split="train", val_fraction=0.3, seed=1)
    val = SceneDataset(labels_dir, SMALL, split="val", val_fraction=0.3, seed=2)
    again = SceneDataset(labels_dir, SMALL, split="val", val_fraction=0.3, seed=9)
    ids = lambda ds: [r.scenario_id for r in ds.records]  # noqa: E731
    assert len(every) == 24 and len(train) > 0 and len(val) > 0
    assert sorted(ids(train) + ids(val)) == sorted(ids(every))
    assert ids(val) == ids(again)
    assert train.augment and not val.augment
    window = replace(every.records[0], scenario_id="long_w91", window_start=91)
    other = replace(window, scenario_id="long_w182", window_start=182)
    assert all(split_of(window, f) == split_of(other, f) for f in np.linspace(0.05, 0.95, 19))


def test_items_are_reproducible_and_vary_by_epoch(labels_dir):
    ds = SceneDataset(labels_dir, SMALL, split="all", seed=5, augment=True)
    first = [ds[i] for i in range(len(ds))]
    again = SceneDataset(labels_dir, SMALL, split="all", seed=5, augment=True)
    for i, sample in enumerate(first):
        other = again[i]
        assert sample["text"] == other["text"]
        np.testing.assert_array_equal(sample["history_valid"], other["history_valid"])
        np.testing.assert_array_equal(sample["future"], other["future"])
    ds.set_epoch(1)
    changed = [
        first[i]["text"] != ds[i]["text"] or not np.array_equal(first[i]["history_valid"], ds[i]["history_valid"])
        for i in range(len(ds))
    ]
    assert any(changed)
    assert ds[len(ds) + 3]["scenario_id"] == first[3]["scenario_id"]  # indices wrap around


def test_interaction_windows_are_indexed(labels_dir):
    ds = SceneDataset(labels_dir, SMALL, split="all")
    assert len(ds.interaction_indices) == 12 and len(ds.other_indices) == 12
    assert all(ds[int(i)]["interaction_labelled"] for i in ds.interaction_indices[:3])
    assert not any(ds[int(i)]["interaction_labelled"] for i in ds.other_indices[:3])


def test_the_mixing_sampler_gives_each_batch_its_share_of_interaction_windows(labels_dir):
    ds = SceneDataset(labels_dir, replace(SMALL, interaction_fraction=0.25), split="all")
    inter = set(ds.interaction_indices.tolist())
    sampler = MixingSampler(ds, 8, num_samples=80, seed=3)
    drawn = list(sampler)
    assert len(drawn) == len(sampler) == 80
    windows = [MixingSampler.window_of(i, len(ds)) for i in drawn]
    for b in range(10):
        assert sum(w in inter for w in windows[8 * b : 8 * b + 8]) == 2
    assert len(set(drawn)) == 80  # repeated windows are distinct draws
    assert list(MixingSampler(ds, 8, num_samples=80, seed=3)) == drawn
    sampler.set_epoch(1)
    assert list(sampler) != drawn
    odd = MixingSampler(ds, 3, num_samples=300, interaction_fraction=0.5, seed=0)
    share = np.mean([MixingSampler.window_of(i, len(ds)) in inter for i in odd])
    assert share == pytest.approx(0.5, abs=0.01)
    stream = iter(MixingSampler(ds, 4, infinite=True))
    assert len([next(stream) for _ in range(100)]) == 100


def test_without_interaction_windows_the_sampler_draws_the_others(labels_dir, tmp_path):
    ds = SceneDataset(labels_dir, SMALL, split="all")
    ds._interaction = np.zeros(0, np.int64)  # as if no window had an interaction prompt
    ds._other = np.arange(len(ds))
    assert len(list(MixingSampler(ds, 8, num_samples=16))) == 16


def test_the_dataset_pickles_and_feeds_a_dataloader(labels_dir):
    ds = SceneDataset(labels_dir, SMALL, split="all", seed=2, augment=True)
    first = ds[4]
    copy = pickle.loads(pickle.dumps(ds))
    assert copy[4]["text"] == first["text"] and copy._cache is not ds._cache
    loader = DataLoader(
        ds, batch_size=4, sampler=MixingSampler(ds, 4, num_samples=8), collate_fn=collate_scenes, num_workers=2
    )
    batches = list(loader)
    assert len(batches) == 2
    for batch in batches:
        assert batch.interaction_labelled.sum().item() == 2
        assert batch.agent_valid[:, 0].all()


def test_a_folder_without_manifest_is_an_input_error(tmp_path):
    with pytest.raises(InputError, match="manifest"):
        SceneDataset(tmp_path, SMALL)


def test_a_record_whose_scenario_file_is_gone_is_an_input_error(tmp_path):
    labels = write_dataset(tmp_path, num_scenes=4)
    (tmp_path / "scenes.tfrecord").unlink()
    with pytest.raises(InputError, match=r"scenes\.tfrecord"):
        SceneDataset(labels, SMALL, split="all")


@pytest.mark.slow
def test_batches_of_a_synthesized_corpus(tmp_path):
    """End to end: synthesized shards, an InterDrive build over them, mixed batches with text."""
    from langtraj.interdrive.dataset import BuildConfig, build_dataset
    from langtraj.synth.factory import FactoryConfig, run_factory

    corpus = tmp_path / "corpus"
    manifest = run_factory(
        FactoryConfig(kinds=("signalized", "onramp"), windows=4, seed=11, out=corpus), progress=False
    )
    build_dataset([corpus / s["file"] for s in manifest["shards"]], tmp_path / "ds", BuildConfig(seed=3))
    ds = SceneDataset(tmp_path / "ds", SampleConfig(text_dropout=0.0), split="all", augment=True)
    assert len(ds) > 0 and len(ds.interaction_indices) > 0
    loader = DataLoader(ds, batch_size=4, sampler=MixingSampler(ds, 4), collate_fn=collate_scenes)
    for batch in loader:
        assert batch.agent_valid[:, 0].all() and batch.map_valid.any(dim=(1, 2)).all()
        at_origin = (batch.current_state[..., :3].abs() < 1e-3).all(dim=-1) & batch.agent_valid
        assert at_origin.any(dim=1).all()  # the focal agent (objects of interest may precede it)
        assert batch.has_text[batch.interaction_labelled].any(dim=1).all()
        assert torch.isfinite(batch.agent_history).all() and torch.isfinite(batch.future).all()
