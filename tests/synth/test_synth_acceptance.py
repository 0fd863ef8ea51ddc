"""The issue's acceptance run: 200 windows of every kind from the command line (slow: minutes)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from langtraj.cli.main import main
from langtraj.scenario.io import read_scenarios
from langtraj.scenario.types import AgentType
from langtraj.synth.network import kind_names
from langtraj.viz import render_frame


@pytest.mark.slow
def test_synth_all_kinds_200_windows_read_back_and_render(tmp_path):
    out = tmp_path / "synth"
    args = ["synth", "--kinds", "all", "--windows", "200", "--seed", "1", "--workers", "2", "--out", str(out)]
    assert main(args) == 0
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["windows"] == 200
    assert set(manifest["per_kind"]) == set(kind_names())
    types = np.zeros(5, int)
    for shard in manifest["shards"]:
        for scenario in read_scenarios(out / shard["file"]):
            types += np.bincount(scenario.agents.types, minlength=5)
            image = render_frame(scenario, scenario.current_index)
            assert image.ndim == 3 and image.std() > 0
    assert types[AgentType.PEDESTRIAN] > 0 and types[AgentType.CYCLIST] > 0
    for kind, stats in manifest["per_kind"].items():
        assert stats["windows"] == stats["target"] == 25, kind
