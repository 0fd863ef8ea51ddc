"""Training samples: text selection, dropouts, dataset split and mixing (scene features: tests/model)."""

from __future__ import annotations

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
from langtraj.model.config import SampleConfig
from langtraj.model.features import collate_scenes
from langtraj.scenario.model import BehaviorEvent
from langtraj.scenario.selection import deciders
from langtraj.training.data import MixingSampler, SceneDataset, build_sample

SMALL = SampleConfig(max_agents=8, max_polylines=12, points_per_polyline=10)
TEXT_ALWAYS = replace(SMALL, text_dropout=0.0, history_dropout=0.0)


def _rng(seed: int = 0) -> np.random.Generator:
    return np.random.default_rng(seed)


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


def test_decision_first_prompts_every_agent_deciding_after_the_current_step_then_fills_the_share():
    scene = make_scenario(12)
    valid_ids = [int(i) for i, v in zip(scene.agents.ids, scene.agents.valid[:, 10], strict=True) if v]
    record = make_record(scene, [make_prompt((i,)) for i in valid_ids[:10]])

    def decision(track: int, step: int, executed: bool = True) -> BehaviorEvent:
        return BehaviorEvent("decision", track, step, step + 5, -1, {"decision_step": step, "executed": executed})

    deciders_ids = valid_ids[5:7]
    events = (
        *(decision(t, 30) for t in deciders_ids),
        decision(valid_ids[0], 5),  # decided before the current step: history shows it
        decision(valid_ids[1], 40, executed=False),
    )
    scene = replace(scene, events=events)
    assert deciders(scene) == frozenset(deciders_ids)
    config = replace(TEXT_ALWAYS, max_agents=16, decision_first=True)
    for seed in range(10):
        sample = build_sample(scene, record, config, _rng(seed))
        got = {int(i) for i, t in zip(sample["agent_id"], sample["text"], strict=True) if t is not None}
        assert set(deciders_ids) <= got and len(got) == 3  # both deciders, then one more: 30 % of 10
    plain = replace(config, decision_first=False)
    hits = sum(
        set(deciders_ids) <= {int(i) for i, t in zip(s["agent_id"], s["text"], strict=True) if t is not None}
        for s in (build_sample(scene, record, plain, _rng(seed)) for seed in range(10))
    )
    assert hits < 10  # without the option the deciders are not always prompted


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


@pytest.fixture(scope="module")
def labels_dir(tmp_path_factory) -> Path:
    return write_dataset(tmp_path_factory.mktemp("training"))


def test_split_is_fixed_by_map_group_and_covers_every_window(labels_dir):
    every = SceneDataset(labels_dir, SMALL, split="all")
    train = SceneDataset(labels_dir, SMALL, split="train", val_fraction=0.3, seed=1)
    val = SceneDataset(labels_dir, SMALL, split="val", val_fraction=0.3, seed=2)
    again = SceneDataset(labels_dir, SMALL, split="val", val_fraction=0.3, seed=9)
    ids = lambda ds: [r.scenario_id for r in ds.records]  # noqa: E731
    assert len(every) == 24 and len(train) > 0 and len(val) > 0
    assert sorted(ids(train) + ids(val)) == sorted(ids(every))
    assert ids(val) == ids(again)
    assert train.augment and not val.augment


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
