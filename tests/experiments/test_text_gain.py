"""The text-gain table: prompt adherence and the ceiling of the text gain on held-out windows."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from dataset_builders import make_record
from scenario_builders import make_scenario
from training.test_training import CONFIG

from langtraj.experiments.text_gain import TextGainConfig, label_consistent_draws, text_gain_table
from langtraj.interdrive.adherence import AdherenceChecker
from langtraj.interdrive.dataset import PromptEntry, write_manifest, write_shard
from langtraj.model.checkpoint import load_model
from langtraj.scenario.io import write_scenarios
from langtraj.training.run import train


def _labelled_dataset(folder: Path, num_scenes: int = 16) -> Path:
    """Toy scenes whose prompts state label keys the labelers find on each scene's logged future."""
    scenes = [make_scenario(5, scenario_id=f"scene-{n:03d}", seed=n) for n in range(num_scenes)]
    source = folder / "scenes.tfrecord"
    write_scenarios(source, scenes)
    records = []
    for n, scene in enumerate(scenes):
        logged = AdherenceChecker.build(scene).logged
        prompts = []
        for track in scene.agents.ids.tolist():
            keys = sorted(f[2] for f in logged if f[0] == "label" and f[1] == track)[:2]
            if keys:
                sentence = f"the target agent is {' and '.join(keys)}"
                prompts.append(
                    PromptEntry(f"@{track} {keys}", (track,), {track: sentence}, None, tuple(keys), "heuristic")
                )
        records.append(make_record(scene, prompts, source=str(source.resolve()), record=n))
    labels = folder / "ds"
    (labels / "labels").mkdir(parents=True)
    write_shard(labels / "labels" / "0000-scenes.jsonl", records)
    write_manifest(labels, {"format_version": 1, "shards": [{"file": "labels/0000-scenes.jsonl"}]})
    return labels


@pytest.fixture(scope="module")
def module(tmp_path_factory):
    folder = tmp_path_factory.mktemp("gain")
    labels = _labelled_dataset(folder)
    config = replace(CONFIG, max_steps=2, data=replace(CONFIG.data, heuristic_label_fraction=1.0))
    return load_model(train(config, labels, folder / "run", progress=False)), labels


def test_the_ceiling_keeps_the_first_following_draws_then_tops_up_in_order():
    follows = np.array([False, True, False, True, True, False])
    assert label_consistent_draws(follows, 2).tolist() == [1, 3]
    assert label_consistent_draws(follows, 4).tolist() == [1, 3, 4, 0]
    assert label_consistent_draws(np.zeros(3, bool), 2).tolist() == [0, 1]


def test_without_extra_draws_the_ceiling_is_the_plain_min_ade(module):
    model, labels = module
    out = text_gain_table(*model, labels, TextGainConfig(num_samples=2, prior_samples=2, steps=2, max_windows=4))
    assert out["checked_agents"] > 0 and out["prompted_agents"] >= out["checked_agents"]
    assert out["prompted_min_ade_ceiling"] == pytest.approx(out["prompted_min_ade_no_text"])
    assert out["prompted_ceiling_gain"] == pytest.approx(0.0, abs=1e-12)
    for name in ("checked_adherence_no_text", "checked_adherence_text", "checked_prior_adherence"):
        assert 0.0 <= out[name] <= 1.0


def test_more_draws_let_more_agents_reach_following_samples(module):
    model, labels = module
    few = text_gain_table(*model, labels, TextGainConfig(num_samples=2, prior_samples=2, steps=2, max_windows=4))
    many = text_gain_table(*model, labels, TextGainConfig(num_samples=2, prior_samples=8, steps=2, max_windows=4))
    assert many["checked_agents"] == few["checked_agents"]
    assert many["checked_full_ceiling"] >= few["checked_full_ceiling"]


def test_prior_samples_must_cover_the_scored_samples():
    with pytest.raises(ValueError, match="prior_samples"):
        TextGainConfig(num_samples=6, prior_samples=4)


def test_the_label_fraction_sets_how_many_agents_are_prompted(module):
    from langtraj.experiments.open_loop import open_loop_table

    model, labels = module  # trained with heuristic_label_fraction 1.0
    kwargs = {"num_samples": 1, "steps": 2, "max_windows": 8}
    default = open_loop_table(*model, labels, **kwargs)
    every = open_loop_table(*model, labels, label_fraction=1.0, **kwargs)
    few = open_loop_table(*model, labels, label_fraction=0.3, **kwargs)
    assert default["prompted_agents"] == every["prompted_agents"] > few["prompted_agents"] > 0
    gain = text_gain_table(*model, labels, TextGainConfig(num_samples=1, prior_samples=1, steps=2, max_windows=8))
    gain_few = text_gain_table(
        *model, labels, TextGainConfig(num_samples=1, prior_samples=1, steps=2, max_windows=8, label_fraction=0.3)
    )
    assert gain["prompted_agents"] > gain_few["prompted_agents"] > 0
