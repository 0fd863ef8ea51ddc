"""bf16 mixed precision and gradient checkpointing in a real training run (docs/model.md, 'Training memory'):
the loss is finite, the learning-rate schedule follows the optimizer (no step is skipped: bf16 needs no
gradient scaler, whose skipped steps made Lightning warn under 16-mixed), and checkpoints resume."""

from __future__ import annotations

import csv
import math
import warnings
from dataclasses import replace
from pathlib import Path

import pytest
import torch
from dataset_builders import write_dataset

from langtraj.model import ModelConfig
from langtraj.model.checkpoint import load_model, read_checkpoint
from langtraj.model.config import SampleConfig
from langtraj.training.config import TrainConfig
from langtraj.training.run import train

CONFIG = TrainConfig(
    name="bf16",
    model=ModelConfig(
        hidden_dim=32, num_heads=4, encoder_layers=1, denoiser_blocks=1, dropout=0.1, use_text=False,
        gradient_checkpointing=True,
    ),
    data=SampleConfig(max_agents=8, max_polylines=12, points_per_polyline=10),
    batch_size=4,
    max_steps=4,
    val_every_steps=4,
    checkpoint_every_steps=2,
    accelerator="cpu",
    precision="bf16-mixed",
)  # fmt: skip


@pytest.fixture(scope="module")
def labels(tmp_path_factory) -> Path:
    return write_dataset(tmp_path_factory.mktemp("bf16"), 12)


def test_bf16_training_with_checkpointing_steps_the_schedule_after_the_optimizer(labels, tmp_path):
    config = replace(CONFIG, val=replace(CONFIG.val, num_samples=2, sample_steps=2, max_batches=1, wosac_scenes=0))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        last = train(config, labels, tmp_path / "run", progress=False)
    assert not [w for w in caught if "lr_scheduler.step()" in str(w.message)]
    checkpoint = read_checkpoint(last)
    assert checkpoint["global_step"] == 4
    assert checkpoint["lr_schedulers"][0]["last_epoch"] == 4  # one schedule step per optimizer step
    assert checkpoint["optimizer_states"][0]["param_groups"][0]["fused"]  # no scaler under bf16: one fused kernel
    rows = list(csv.DictReader((tmp_path / "run" / "logs" / "csv" / "version_0" / "metrics.csv").open()))
    losses = [float(r["train/loss"]) for r in rows if r.get("train/loss")]
    minade = [float(r["val/minade"]) for r in rows if r.get("val/minade")]
    assert losses and all(math.isfinite(v) for v in losses + minade) and minade
    model, _ = load_model(last)
    assert model.config.gradient_checkpointing and next(model.parameters()).dtype == torch.float32  # fp32 weights
