"""A tiny trained checkpoint (2 steps on toy scenes) shared by the simulation tests."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from dataset_builders import write_dataset

from langtraj.cli.main import main

TINY = {
    "name": "sim-test",
    "stage": 2,
    "model": {"hidden_dim": 32, "num_heads": 4, "encoder_layers": 1, "denoiser_blocks": 1, "dropout": 0.0},
    "data": {"max_agents": 8, "max_polylines": 12, "points_per_polyline": 10},
    "batch_size": 4,
    "max_steps": 2,
    "val_every_steps": 1000,
    "checkpoint_every_steps": 2,
}


@pytest.fixture(scope="package")
def tiny_run(tmp_path_factory) -> tuple[Path, Path]:
    """(checkpoint, scenario file of toy scenes with tracks 7, 17, 37, 47 valid at the current step)."""
    root = tmp_path_factory.mktemp("sim")
    labels = write_dataset(root, 8)
    config = root / "tiny.yaml"
    config.write_text(yaml.safe_dump(TINY))
    assert main(["train", "--config", str(config), "--data", str(labels), "--out", str(root / "run")]) == 0
    return root / "run" / "checkpoints" / "last.ckpt", root / "scenes.tfrecord"
