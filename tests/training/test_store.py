"""The feature store: stored samples are today's `scene_sample` arrays, datasets read them unchanged, builds
resume, and stores built for other settings are refused (docs/model.md, 'The feature store')."""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch
from dataset_builders import write_dataset
from scenario_builders import make_scenario

from langtraj.errors import InputError
from langtraj.interdrive.dataset import iter_records, load_window
from langtraj.interdrive.labels import WindowLabels
from langtraj.model.config import ModelConfig, SampleConfig
from langtraj.model.features import SAMPLE_ARRAYS, collate_scenes, scene_sample
from langtraj.model.langtraj import LangTraj
from langtraj.model.targets import fit_actions
from langtraj.scenario.io import write_scenarios
from langtraj.scenario.model import BehaviorEvent
from langtraj.training import store as store_module
from langtraj.training.data import SceneDataset
from langtraj.training.store import (
    FeatureStore,
    build_store,
    default_store_path,
    labelled_jobs,
    scenario_jobs,
)

SMALL = SampleConfig(max_agents=8, max_polylines=12, points_per_polyline=10)
REPO = Path(__file__).resolve().parents[2]


def _quiet(_: str) -> None:
    pass


@pytest.fixture
def labels_dir(tmp_path, monkeypatch) -> Path:
    monkeypatch.setattr(store_module, "CHUNK_WINDOWS", 5)  # several chunks from 24 windows
    return write_dataset(tmp_path)


def _same(a: dict, b: dict) -> None:
    for name in SAMPLE_ARRAYS:
        assert a[name].dtype == b[name].dtype, name
        assert a[name].shape == b[name].shape, name
        np.testing.assert_allclose(a[name], b[name], rtol=0, atol=1e-6, err_msg=name)
    assert a["scenario_id"] == b["scenario_id"]
    assert a["text"] == b["text"]


def test_stored_samples_are_the_scene_samples_of_their_windows(labels_dir):
    store = build_store(labelled_jobs(labels_dir, SMALL), default_store_path(labels_dir, SMALL), say=_quiet)
    records = [r for _, shard in iter_records(labels_dir) for r in shard]
    assert len(store) == len(records) == 24 and len(store.chunks) == 5
    for row, record in enumerate(records):
        assert store.rows[row].record == replace(record, labels=WindowLabels(record.scenario_id))  # prompts kept
        assert store.rows[row].record.prompts == record.prompts and record.prompts
        _same(store.sample(row), scene_sample(load_window(record), SMALL))


def test_stored_target_actions_are_the_inverse_dynamics_of_their_windows(labels_dir):
    """The store fits each window's target actions once, as the model would fit them in every step."""
    store = build_store(labelled_jobs(labels_dir, SMALL), default_store_path(labels_dir, SMALL), say=_quiet)
    rows = [store.sample(row) for row in range(len(store))]
    batch = collate_scenes(rows)
    assert batch.target_actions is not None and batch.target_actions.shape == (24, 8, 16, 2)
    assert batch.target_valid.any() and not batch.target_valid.all()  # padded agents and invalid steps
    model = LangTraj(ModelConfig(hidden_dim=16, num_heads=2, encoder_layers=0, denoiser_blocks=1, use_text=False))
    stored, stored_valid = model.target_actions(batch)
    fitted, fitted_valid = model.fit_actions(batch.current_state, batch.future, batch.future_valid, batch.agent_valid)
    assert torch.equal(stored_valid, fitted_valid)
    torch.testing.assert_close(stored, fitted, rtol=0, atol=1e-6)
    physical, _ = fit_actions(model.dynamics, batch.current_state, batch.future, batch.future_valid,
                              batch.agent_valid, 16)  # fmt: skip
    torch.testing.assert_close(batch.target_actions, physical, rtol=0, atol=1e-5)
    # a model of another horizon (closed-loop training's 8 actions) refits rather than read 16-action targets
    short = LangTraj(ModelConfig(hidden_dim=16, num_heads=2, encoder_layers=0, denoiser_blocks=1, use_text=False,
                                 num_actions=8))  # fmt: skip
    eight, _ = short.target_actions(batch)
    assert eight.shape == (24, 8, 8, 2)
    # a batch without stored targets (decoded windows) fits them in the step, with the same result
    decoded = collate_scenes([scene_sample(load_window(r.record), SMALL) for r in store.rows])
    assert decoded.target_actions is None
    torch.testing.assert_close(model.target_actions(decoded)[0], stored, rtol=0, atol=1e-6)


def test_a_dataset_reads_the_labels_folders_store_and_gives_the_same_items(labels_dir):
    config = replace(SMALL, text_dropout=0.3, history_dropout=0.5)
    decoded = SceneDataset(labels_dir, config, split="train", seed=3, store=None)
    assert decoded.store is None
    build_store(labelled_jobs(labels_dir, config), default_store_path(labels_dir, config), say=_quiet)
    stored = SceneDataset(labels_dir, config, split="train", seed=3)  # "auto" finds it
    assert stored.store is not None and stored.records == decoded.records
    for index in [*range(len(decoded)), len(decoded) + 3, 5 * len(decoded) + 1]:
        a, b = stored[index], decoded[index]
        _same(a, b)
        assert a["interaction_labelled"] == b["interaction_labelled"]


def test_a_store_of_other_sample_settings_is_not_used_automatically_and_refused_by_name(labels_dir):
    other = replace(SMALL, max_polylines=20)
    path = default_store_path(labels_dir, other)
    build_store(labelled_jobs(labels_dir, other), path, say=_quiet)
    assert SceneDataset(labels_dir, SMALL).store is None  # its own digest's folder does not exist
    with pytest.raises(InputError, match=r"store\.json.*key.*max_polylines 20 != 12"):
        SceneDataset(labels_dir, SMALL, store=path)
    with pytest.raises(InputError, match="max_polylines"):
        SceneDataset(path, SMALL)


def test_a_store_must_hold_every_window_of_the_labels(tmp_path, labels_dir):
    records = [r for _, shard in iter_records(labels_dir) for r in shard]
    partial = build_store([store_module.StoreJob(0, SMALL, records=tuple(records[:3]))], tmp_path / "s", say=_quiet)
    assert len(partial) == 3
    with pytest.raises(InputError, match="21 windows of the labels are not in it"):
        SceneDataset(labels_dir, SMALL, split="all", store=tmp_path / "s")
    stale = default_store_path(labels_dir, SMALL)  # where "auto" looks: a store older than the labels
    build_store([store_module.StoreJob(0, SMALL, records=tuple(records[:3]))], stale, say=_quiet)
    with pytest.raises(InputError, match=r"21 windows of the labels are not in it.*rebuild"):
        SceneDataset(labels_dir, SMALL, split="all")


def test_a_killed_build_resumes_with_the_chunks_not_yet_done(labels_dir, monkeypatch):
    jobs = labelled_jobs(labels_dir, SMALL)
    out = labels_dir / "store"
    real = store_module._build_chunk
    built: list[int] = []

    def dies_on_the_third(job, partial):
        if len(built) == 2:
            raise KeyboardInterrupt
        built.append(job.number)
        return real(job, partial)

    monkeypatch.setattr(store_module, "_build_chunk", dies_on_the_third)
    with pytest.raises(KeyboardInterrupt):
        build_store(jobs, out, say=_quiet)
    assert not out.exists() and sorted(p.name for p in out.with_name("store.partial").glob("chunk-*")) == [
        "chunk-00000",
        "chunk-00001",
    ]
    monkeypatch.setattr(store_module, "_build_chunk", real)
    said: list[str] = []
    store = build_store(jobs, out, say=said.append)
    assert said[0] == "feature store: resuming, 2 of 5 chunks done before"
    assert not out.with_name("store.partial").exists()
    fresh = build_store(jobs, labels_dir / "fresh", say=_quiet)
    for row in range(len(store)):
        _same(store.sample(row), fresh.sample(row))
    with pytest.raises(InputError, match="already there"):
        build_store(jobs, out, say=_quiet)


def test_a_resumed_build_rebuilds_a_chunk_whose_windows_changed_under_the_same_first_id(labels_dir, monkeypatch):
    jobs = labelled_jobs(labels_dir, SMALL)
    out = labels_dir / "store"
    real = store_module._build_chunk

    def dies_on_the_second(job, partial):
        if job.number == 1:
            raise KeyboardInterrupt
        return real(job, partial)

    monkeypatch.setattr(store_module, "_build_chunk", dies_on_the_second)
    with pytest.raises(KeyboardInterrupt):
        build_store(jobs, out, say=_quiet)
    assert (out.with_name("store.partial") / "chunk-00000").is_dir()
    # The labels rebuilt since: chunk 0 holds the same first window and as many, but others after it.
    first, *rest = jobs[0].records
    others = jobs[1].records[: len(rest)]
    changed = [replace(jobs[0], records=(first, *others)), *jobs[1:]]
    monkeypatch.setattr(store_module, "_build_chunk", real)
    said: list[str] = []
    store = build_store(changed, out, say=said.append)
    assert not any("resuming" in line for line in said)  # the chunk on disk is of other windows: built anew
    assert [r.record.scenario_id for r in store.rows[: len(rest) + 1]] == [x.scenario_id for x in (first, *others)]
    fresh = build_store(changed, labels_dir / "fresh", say=_quiet)
    for row in range(len(store)):
        _same(store.sample(row), fresh.sample(row))


def test_stage_one_stores_every_window_of_scenario_files_without_labels(tmp_path):
    decision = BehaviorEvent("decision", 7, 40, 60, -1, {"executed": True, "decision_step": 40, "decision": "turn"})
    scenes = [make_scenario(5, scenario_id=f"s{n}", seed=n) for n in range(3)]
    scenes[1] = replace(scenes[1], events=(*scenes[1].events, decision))
    long = make_scenario(4, 200, scenario_id="long")  # cut into two 91-step windows
    write_scenarios(tmp_path / "a.tfrecord", scenes)
    write_scenarios(tmp_path / "b.tfrecord", [long])
    store = build_store(
        scenario_jobs([tmp_path / "a.tfrecord", tmp_path / "b.tfrecord"], SMALL), tmp_path / "store", say=_quiet
    )
    assert [r.record.scenario_id for r in store.rows] == ["s0", "s1", "s2", "long_w0", "long_w91"]
    assert store.rows[1].deciders == frozenset({7}) and not store.rows[0].deciders
    assert all(not r.record.prompts and not r.record.labels.agent_labels for r in store.rows)
    for row in range(len(store)):
        _same(store.sample(row), scene_sample(load_window(store.rows[row].record), SMALL))
    every = SceneDataset(tmp_path / "store", SMALL, split="all")
    assert len(every) == 5 and every.store is not None
    assert all(t is None for t in every[1]["text"])
    for other in (None, tmp_path / "store"):  # a store folder is its own store: naming another is an error
        with pytest.raises(ValueError, match="is itself a feature store"):
            SceneDataset(tmp_path / "store", SMALL, split="all", store=other)


def test_a_corrupt_store_gives_one_line_errors_naming_the_file(tmp_path, labels_dir):
    path = tmp_path / "s"
    build_store(labelled_jobs(labels_dir, SMALL), path, say=_quiet)
    meta = json.loads((path / "store.json").read_text())
    assert set(meta) == {"key", "chunks"}
    meta["chunks"][0]["windows"] += 1
    (path / "store.json").write_text(json.dumps(meta))
    with pytest.raises(InputError, match=r"5 rows, store\.json says 6"):
        FeatureStore(path)
    (path / "store.json").write_text("{")
    with pytest.raises(InputError, match=r"store\.json"):
        FeatureStore(path)
    with pytest.raises(InputError, match="not a feature store"):
        FeatureStore(tmp_path)


def test_the_cli_builds_a_labels_folders_store_for_a_preset(tmp_path):
    labels = write_dataset(tmp_path)
    config = REPO / "configs" / "tiny.yaml"
    run = [sys.executable, "-m", "langtraj.cli.main", "features"]
    done = subprocess.run([*run, "build", "--config", str(config), "--labels", str(labels)], capture_output=True)
    assert done.returncode == 0, done.stderr.decode()
    (store,) = (labels / "features").iterdir()
    assert done.stdout.decode().splitlines()[-1] == f"feature store {store}: 24 windows"
    info = subprocess.run([*run, "info", str(store)], capture_output=True, text=True)
    assert info.returncode == 0 and "24 windows in 1 chunks" in info.stdout and "max_agents 24" in info.stdout
    bad = subprocess.run([*run, "build", "--config", str(config)], capture_output=True, text=True)
    assert bad.returncode != 0 and bad.stderr.strip().count("\n") == 0 and "--labels" in bad.stderr
