"""A tiny trained checkpoint (2 steps on toy scenes) shared by the simulation tests."""

from __future__ import annotations

from pathlib import Path

import pytest
from dataset_builders import train_tiny


@pytest.fixture(scope="package")
def tiny_run(tmp_path_factory) -> tuple[Path, Path]:
    """(checkpoint, scenario file of toy scenes with tracks 7, 17, 37, 47 valid at the current step)."""
    return train_tiny(tmp_path_factory.mktemp("sim"), 8)
