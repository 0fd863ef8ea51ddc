"""The command tests' shared scene file."""

from __future__ import annotations

from pathlib import Path

import pytest
from scenario_builders import make_scenario

from langtraj.scenario.io import write_scenarios


@pytest.fixture
def toy_file(tmp_path: Path) -> Path:
    path = tmp_path / "toy.tfrecord"
    write_scenarios(path, [make_scenario(), make_scenario(scenario_id="b")])
    return path
