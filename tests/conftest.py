"""Shared fixtures: the real scenario files in ../shared/data/real (skipped when absent), small
scenarios built in memory, and a tiny trained checkpoint."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
import torch
from dataset_builders import train_tiny
from scenario_builders import make_scenario

from langtraj.scenario import Scenario

REPO_ROOT = Path(__file__).resolve().parents[1]
REAL_DATA_DIR = Path(os.environ.get("LANGTRAJ_REAL_DATA", REPO_ROOT.parent / "shared" / "data" / "real"))
WOMD_FILE = "motion_data_one_scenario.tfrecord"


@pytest.fixture(scope="session")
def real_data_dir() -> Path:
    """The folder of real Waymo / nuScenes files; the test is skipped when it is absent."""
    if not (REAL_DATA_DIR / WOMD_FILE).is_file():
        pytest.skip(f"real scenario files not found in {REAL_DATA_DIR} (set LANGTRAJ_REAL_DATA to override)")
    return REAL_DATA_DIR


@pytest.fixture(scope="session")
def wosac_reference(real_data_dir: Path) -> Path:
    """The WOSAC reference folder (rollouts and the official implementation's metrics for them)."""
    folder = real_data_dir.parent / "wosac_reference"
    if not (folder / "official_metrics.json").is_file():
        pytest.skip(f"WOSAC reference rollouts not found in {folder}")
    return folder


@pytest.fixture(scope="session")
def real_files(real_data_dir: Path) -> list[Path]:
    return sorted(p for p in real_data_dir.iterdir() if p.suffix in (".tfrecord", ".pkl"))


@pytest.fixture
def toy_scenario() -> Scenario:
    return make_scenario()


@pytest.fixture(scope="package")
def tiny_run(tmp_path_factory) -> tuple[Path, Path]:
    """A tiny trained checkpoint (2 steps on toy scenes), shared by the simulation and command tests:
    (checkpoint, scenario file of toy scenes with tracks 7, 17, 37, 47 valid at the current step)."""
    return train_tiny(tmp_path_factory.mktemp("sim"), 8)


@pytest.fixture(autouse=True)
def _torch_global_state_restored():
    """No test leaves torch's process-wide settings (threads, default dtype, grad mode) other than it found them: a
    later test would run, and time, under them. A fixture that changes one for a module restores it at teardown."""
    before = (torch.get_num_threads(), torch.get_default_dtype(), torch.is_grad_enabled())
    yield
    after = (torch.get_num_threads(), torch.get_default_dtype(), torch.is_grad_enabled())
    assert after == before, f"torch's (threads, default dtype, grad mode) changed from {before} to {after}"


@pytest.fixture
def one_torch_thread():
    """One torch thread for a test whose pinned figures came from one (matrix products sum in another order on
    more), restored after."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)
