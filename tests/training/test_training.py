"""Training runs: the loss falls, checkpoints resume exactly, bad configurations and checkpoints fail
clearly. Small model, toy scenes, CPU."""

from __future__ import annotations

import csv
import shutil
from dataclasses import replace
from pathlib import Path

import pytest
import torch
from dataset_builders import write_dataset

from langtraj.errors import InputError
from langtraj.model import ModelConfig
from langtraj.model.checkpoint import load_model, read_checkpoint
from langtraj.model.config import SampleConfig
from langtraj.settings import read_yaml
from langtraj.training.config import ClosedLoopConfig, TrainConfig, load_config
from langtraj.training.run import train
from langtraj.training.store import build_store, default_store_path, labelled_jobs

ROOT = Path(__file__).resolve().parents[2]
CONFIG = TrainConfig(
    name="test",
    model=ModelConfig(hidden_dim=32, num_heads=4, encoder_layers=1, denoiser_blocks=1, dropout=0.0, use_text=False),
    data=SampleConfig(max_agents=8, max_polylines=12, points_per_polyline=10),
    batch_size=4,
    max_steps=20,
    val_every_steps=1000,
    checkpoint_every_steps=3,
)


@pytest.fixture(scope="module")
def labels(tmp_path_factory) -> Path:
    return write_dataset(tmp_path_factory.mktemp("train"), 24)


def _losses(run: Path) -> list[float]:
    rows = list(csv.DictReader((run / "logs" / "csv" / "version_0" / "metrics.csv").open()))
    return [float(r["train/loss"]) for r in rows if r.get("train/loss")]


def test_twenty_steps_lower_the_loss(labels, tmp_path):
    config = replace(CONFIG, optim=replace(CONFIG.optim, lr=3e-3, warmup_steps=1))
    last = train(config, labels, tmp_path / "run", progress=False)
    losses = _losses(tmp_path / "run")
    assert len(losses) == 2  # logged every 10 steps
    assert losses[-1] < losses[0]
    assert last.is_file() and read_checkpoint(last)["global_step"] == 20


CLOSED_LOOP = replace(
    CONFIG,
    objective="closed_loop",
    model=replace(CONFIG.model, num_actions=8, diffusion_steps=5),
    val=replace(CONFIG.val, sample_steps=5, wosac_scenes=0),
    closed_loop=ClosedLoopConfig(candidates=2),
)


@pytest.mark.parametrize("base", [CONFIG, CLOSED_LOOP], ids=["denoising", "closed_loop"])
def test_resuming_from_a_checkpoint_continues_exactly(labels, tmp_path, base):
    config = replace(base, max_steps=6)
    train(config, labels, tmp_path / "a", progress=False)
    middle = tmp_path / "a" / "checkpoints" / "step0000003.ckpt"
    assert middle.is_file()
    train(config, labels, tmp_path / "b", resume=str(middle), progress=False)
    a = read_checkpoint(tmp_path / "a" / "checkpoints" / "last.ckpt")
    b = read_checkpoint(tmp_path / "b" / "checkpoints" / "last.ckpt")
    assert a["global_step"] == b["global_step"] == 6
    for key, value in a["state_dict"].items():
        torch.testing.assert_close(b["state_dict"][key], value, atol=1e-6, rtol=1e-5, msg=key)


def test_resume_auto_picks_up_the_last_checkpoint(labels, tmp_path):
    config = replace(CONFIG, max_steps=3)
    train(config, labels, tmp_path / "run", progress=False)
    train(config, labels, tmp_path / "run", resume="auto", max_steps=5, progress=False)
    assert read_checkpoint(tmp_path / "run" / "checkpoints" / "last.ckpt")["global_step"] == 5
    assert not list((tmp_path / "run" / "checkpoints").glob(".*.partial"))


def test_milestone_checkpoints_are_kept_and_training_reads_a_feature_store_alike(labels, tmp_path):
    """`keep_every_steps` keeps every milestone (the rolling checkpoints keep only the latest two); a run on
    the labels folder's feature store ends with the same weights as one decoding every window."""
    config = replace(CONFIG, max_steps=6, keep_every_steps=2)
    train(config, labels, tmp_path / "decoded", progress=False)
    kept = sorted(p.name for p in (tmp_path / "decoded" / "checkpoints" / "kept").glob("*.ckpt"))
    assert kept == ["step0000002.ckpt", "step0000004.ckpt", "step0000006.ckpt"]
    store = default_store_path(labels, config.data)
    build_store(labelled_jobs(labels, config.data), store, say=lambda _: None)
    try:
        train(config, labels, tmp_path / "stored", progress=False)
    finally:
        shutil.rmtree(store.parent)  # the module's other tests decode
    a = read_checkpoint(tmp_path / "decoded" / "checkpoints" / "last.ckpt")["state_dict"]
    b = read_checkpoint(tmp_path / "stored" / "checkpoints" / "last.ckpt")["state_dict"]
    for key, value in a.items():
        torch.testing.assert_close(b[key], value, atol=1e-6, rtol=1e-5, msg=key)


def test_checkpoints_leave_out_the_pretrained_text_weights_and_reload(labels, tmp_path):
    config = replace(CONFIG, stage=2, model=replace(CONFIG.model, use_text=True), max_steps=2)
    last = train(config, labels, tmp_path / "run", progress=False)
    state = read_checkpoint(last)["state_dict"]
    assert not [k for k in state if k.startswith("model.text_encoder.encoder.") and "lora_" not in k]
    assert [k for k in state if "lora_" in k]
    model, data = load_model(last)
    assert model.text_encoder is not None and data == config.data


def test_bad_checkpoints_and_configs_are_input_errors(tmp_path):
    junk = tmp_path / "junk.ckpt"
    junk.write_bytes(b"not a checkpoint")
    with pytest.raises(InputError, match=r"junk\.ckpt"):
        read_checkpoint(junk)
    foreign = tmp_path / "foreign.ckpt"
    torch.save({"state_dict": {}}, foreign)
    with pytest.raises(InputError, match="not a LangTraj checkpoint"):
        read_checkpoint(foreign)
    bad = tmp_path / "bad.yaml"
    bad.write_text("stage: 3\n")
    with pytest.raises(InputError, match="stage must be 1 or 2"):
        load_config(bad)
    bad.write_text("colour: red\n")
    with pytest.raises(InputError, match="unknown keys colour"):
        load_config(bad)
    bad.write_text("model: {history_steps: 5}\n")  # the samples keep their default 11
    with pytest.raises(InputError, match=r"data\.history_steps.*11 steps of history in the samples, the model reads 5"):
        load_config(bad)


EXPERIMENT_CONFIGS = sorted((ROOT / "configs" / "experiments").glob("*.yaml"))
TRAINING_RUNS = [p for p in EXPERIMENT_CONFIGS if "experiment" not in read_yaml(p)]
"""The training runs of the experiments (the other files there configure the tables, tests/experiments)."""


@pytest.mark.parametrize("path", TRAINING_RUNS, ids=lambda p: p.stem)
def test_the_experiment_training_runs_load(path):
    config = load_config(path)
    assert config.model.use_text == (config.stage == 2)  # stage 1 (the scaling cells) has no text branch


def test_a_bad_preset_is_one_line_and_exit_2(labels, tmp_path, capsys):
    from langtraj.cli.main import main

    bad = tmp_path / "bad.yaml"
    bad.write_text(f"extends: {ROOT / 'configs' / 'tiny.yaml'}\ndata: {{max_agents: 0}}\n")
    assert main(["train", "--config", str(bad), "--data", str(labels), "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.endswith("data.max_agents: must be >= 1, got 0") and len(err.splitlines()) == 1
    assert not (tmp_path / "run").exists()


def test_validation_reports_min_ade_and_a_small_wosac_evaluation(labels, tmp_path):
    from langtraj.training.config import ValConfig

    val = ValConfig(num_samples=2, sample_steps=2, max_batches=1, wosac_scenes=1, wosac_rollouts=2)
    config = replace(CONFIG, max_steps=2, val_every_steps=2, val=val)
    train(config, labels, tmp_path / "run", progress=False)
    rows = list(csv.DictReader((tmp_path / "run" / "logs" / "csv" / "version_0" / "metrics.csv").open()))
    logged = {k for r in rows for k, v in r.items() if v}
    assert {"val/minade", "val/cv_minade", "val/wosac_metametric", "val/wosac_map_based_metrics"} <= logged
    value = next(float(r["val/wosac_metametric"]) for r in rows if r.get("val/wosac_metametric"))
    assert 0.0 < value < 1.0


def test_a_checkpoint_of_another_model_version_is_refused(labels, tmp_path):
    last = train(replace(CONFIG, max_steps=1), labels, tmp_path / "run", progress=False)
    checkpoint = torch.load(last, weights_only=True)
    del checkpoint["state_dict"][next(k for k in checkpoint["state_dict"] if "denoiser" in k)]
    older = tmp_path / "older.ckpt"
    torch.save(checkpoint, older)
    with pytest.raises(InputError, match=r"do not match this version of the model; missing model\.denoiser"):
        load_model(older)


def test_a_checkpoint_with_the_obsolete_null_embedding_still_loads(labels, tmp_path):
    config = replace(CONFIG, stage=2, model=replace(CONFIG.model, use_text=True), max_steps=1)
    last = train(config, labels, tmp_path / "run", progress=False)
    checkpoint = torch.load(last, weights_only=True)
    checkpoint["state_dict"]["model.text_encoder.null_embedding"] = torch.zeros(config.model.hidden_dim)
    older = tmp_path / "older.ckpt"
    torch.save(checkpoint, older)
    model, _ = load_model(older)
    for key, value in load_model(last)[0].state_dict().items():
        assert torch.equal(model.state_dict()[key], value), key


def test_a_compiled_stage_two_run_trains_validates_and_saves_what_an_eager_run_does(labels, tmp_path):
    """`compile: true` through Lightning: the compiled step (with text and LoRA), eager validation, checkpoints
    whose weights carry their usual names and match an eager run's."""
    config = replace(CONFIG, stage=2, model=replace(CONFIG.model, use_text=True), max_steps=3, val_every_steps=3)
    eager = train(config, labels, tmp_path / "eager", progress=False)
    compiled = train(replace(config, compile=True), labels, tmp_path / "compiled", progress=False)
    a, b = read_checkpoint(eager)["state_dict"], read_checkpoint(compiled)["state_dict"]
    assert a.keys() == b.keys()
    for key, value in a.items():
        torch.testing.assert_close(b[key], value, atol=1e-4, rtol=1e-3, msg=key)
    model, _ = load_model(compiled)
    assert not model.compiled  # a checkpoint loads eager; compiling is the caller's choice
    rows = list(csv.DictReader((tmp_path / "compiled" / "logs" / "csv" / "version_0" / "metrics.csv").open()))
    assert [r for r in rows if r.get("val/loss")] and len(_losses(tmp_path / "compiled")) > 0  # validated, trained
