"""`langtraj submit`: rollouts folder + scenarios -> checked submission shards and package."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scenario_builders import make_scenario

from cli.helpers import METADATA
from langtraj.cli.main import main
from langtraj.metrics.submission import iter_submission_rollouts, read_submission
from langtraj.rollouts import Rollouts
from langtraj.rollouts.baselines import generate_baseline
from langtraj.scenario.io import write_scenarios


@pytest.fixture
def inputs(tmp_path: Path) -> tuple[Path, Path, Path]:
    scenes = [make_scenario(5, scenario_id=f"s{i}", seed=i) for i in range(3)]
    scenario_file = tmp_path / "scenes.tfrecord"
    write_scenarios(scenario_file, scenes)
    rollouts = tmp_path / "rollouts"
    for scene in scenes:
        generate_baseline("constant_velocity", scene).save(rollouts / f"{scene.scenario_id}.npz")
    meta = tmp_path / "meta.json"
    meta.write_text(json.dumps(METADATA))
    return scenario_file, rollouts, meta


def test_submit_writes_shards_that_read_back(inputs, tmp_path, capsys):
    scenario_file, rollouts, meta = inputs
    out = tmp_path / "submission"
    code = main(
        ["submit", str(scenario_file), str(rollouts), "--metadata", str(meta), "--out", str(out), "--shard-size", "2"]
    )
    assert code == 0, capsys.readouterr().err
    shards = read_submission(out / "submission.tar.gz")
    assert len(shards) == 2 and shards[0].account_name == METADATA["account_name"]
    back = {r.scenario_id: r for r in iter_submission_rollouts(out / "submission.tar.gz")}
    assert sorted(back) == ["s0", "s1", "s2"]
    original = Rollouts.load(rollouts / "s1.npz")
    np.testing.assert_array_equal(back["s1"].x, original.x)


def test_submit_refuses_rollouts_that_break_the_rules(inputs, tmp_path, capsys):
    scenario_file, rollouts, meta = inputs
    scene = make_scenario(5, scenario_id="s2", seed=2)
    generate_baseline("constant_velocity", scene, 16).save(rollouts / "s2.npz")
    out = tmp_path / "submission"
    code = main(["submit", str(scenario_file), str(rollouts), "--metadata", str(meta), "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and "s2.npz" in err and "16 rollouts, expected 32" in err
    assert not out.exists() or not any(out.iterdir())


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"account_name": "nobody"}, "not the e-mail"),
        ({"acknowledge_complies_with_closed_loop_requirement": False}, "acknowledge_complies"),
        ({"colour": "red"}, "unknown fields colour"),
    ],
)
def test_submit_checks_the_metadata_first(inputs, tmp_path, capsys, change, message):
    scenario_file, rollouts, meta = inputs
    meta.write_text(json.dumps({**METADATA, **change}))
    code = main(["submit", str(scenario_file), str(rollouts), "--metadata", str(meta), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 2 and message in err and str(meta) in err
