"""Experiment configs: every committed YAML under configs/experiments/ loads into its settings; a YAML file and the
flags it stands for give the same settings and the same table; mistakes are one line naming the file and key."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml
from dataset_builders import write_dataset

from langtraj.cli.main import main
from langtraj.errors import InputError
from langtraj.experiments import EXPERIMENTS, experiment_settings
from langtraj.experiments.common import DatasetSpec
from langtraj.experiments.realism import Method
from langtraj.settings import read_yaml

CONFIGS = Path(__file__).resolve().parents[2] / "configs" / "experiments"


TABLES = [p for p in sorted(CONFIGS.glob("*.yaml")) if "experiment" in read_yaml(p)]
"""The committed table configs (the other files there are training runs, tests/training/test_training.py)."""


def test_every_table_has_a_committed_config():
    assert {read_yaml(p)["experiment"] for p in TABLES} == set(EXPERIMENTS.names())


@pytest.mark.parametrize("path", TABLES, ids=lambda p: p.name)
def test_every_committed_experiment_config_loads(path):
    data = read_yaml(path)
    settings = experiment_settings(data["experiment"], path, {})
    assert isinstance(settings, EXPERIMENTS.get(data["experiment"]).settings)


def test_a_config_file_and_its_flags_give_the_same_settings(tmp_path):
    config = tmp_path / "realism.yaml"
    config.write_text(
        yaml.safe_dump(
            {
                "experiment": "realism",
                "datasets": ["toy=labels:all:2", {"name": "more", "labels": "other"}],
                "methods": ["cv=constant_velocity", {"name": "m", "checkpoint": "x.ckpt", "guidance": ["on_road=1"]}],
                "windows": 2,
            }
        )
    )
    flags = {
        "datasets": ["toy=labels:all:2", "more=other"],
        "methods": ["cv=constant_velocity", "m=x.ckpt|guidance=on_road:1"],
        "windows": 2,
    }
    from_file = experiment_settings("realism", config, {})
    assert from_file == experiment_settings("realism", None, flags)
    assert from_file.datasets[0] == DatasetSpec("toy", Path("labels"), "all", 2)
    assert from_file.methods[1] == Method("m", checkpoint=Path("x.ckpt"), guidance=("on_road=1",))
    # Flags given beside the file override its values.
    assert experiment_settings("realism", config, {"windows": 5, "seed": 3}).windows == 5


@pytest.mark.parametrize(
    ("body", "message"),
    [
        ({"experiment": "realism", "datasets": ["a=b"], "methods": ["s=stationary"], "windos": 2}, "unknown keys"),
        ({"experiment": "realism", "datasets": ["a=b"], "methods": ["s=stationary"], "windows": "2"}, "windows: exp"),
        ({"experiment": "realism", "datasets": ["a=b"]}, "missing methods"),
        ({"experiment": "realism", "datasets": ["a=b:test"], "methods": ["s=stationary"]}, "datasets\\[0\\]: split"),
        ({"experiment": "realism", "datasets": ["a=b"], "methods": [{"name": "s", "baseline": "walk"}]}, "walk"),
        ({"experiment": "realism", "datasets": ["a=b"], "methods": [{"name": "m"}]}, "a baseline or a checkpoint"),
        ({"experiment": "closed-loop", "checkpoint": "x.ckpt", "datasets": ["a=b"]}, "configures 'closed-loop'"),
    ],
)
def test_config_mistakes_are_one_line_naming_the_file_and_key(tmp_path, body, message):
    config = tmp_path / "bad.yaml"
    config.write_text(yaml.safe_dump(body))
    with pytest.raises(InputError, match=message) as caught:
        experiment_settings("realism", config, {})
    assert str(config) in str(caught.value) and "\n" not in str(caught.value)


def test_a_table_from_a_config_file_equals_the_table_from_its_flags(tmp_path, capsys):
    labels = write_dataset(tmp_path, 2)
    flags = ["--data", f"toy={labels}:all:2", "--method", "cv=constant_velocity", "--method", "still=stationary"]
    assert main(["experiment", "realism", *flags, "--json", str(tmp_path / "flags.json")]) == 0
    config = tmp_path / "realism.yaml"
    body = {"experiment": "realism", "datasets": [f"toy={labels}:all:2"], "methods": flags[3::2]}
    config.write_text(yaml.safe_dump(body))
    assert main(["experiment", "realism", "--config", str(config), "--json", str(tmp_path / "file.json")]) == 0
    from_flags, from_file = (json.loads((tmp_path / f).read_text()) for f in ("flags.json", "file.json"))
    for result in (from_flags, from_file):  # timings differ run to run
        for row in result["toy"]["table"].values():
            row.pop("seconds_per_simulation")
    assert from_file == from_flags
    capsys.readouterr()
    assert main(["experiment", "realism", "--method", "cv=constant_velocity"]) == 2
    assert "missing datasets" in capsys.readouterr().err
