"""`langtraj experiment failures` and the realism table's breakdown by cause: baselines only (no model), on toy
windows, some named as synthesized windows of a network kind; every share per cause sums to its kind's share."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import pytest
from dataset_builders import make_record
from scenario_builders import make_scenario

from langtraj.cli.main import main
from langtraj.errors import InputError
from langtraj.experiments import experiment_settings
from langtraj.experiments.common import window_kind
from langtraj.experiments.failures import LOG_ROW
from langtraj.experiments.realism import Method, breakdown_markdown, realism_table
from langtraj.interdrive.dataset import write_manifest, write_shard
from langtraj.scenario.ids import synth_window_id
from langtraj.scenario.io import write_scenarios
from langtraj.sim.config import SimConfig
from langtraj.sim.failures import BREAKDOWN_KEYS, COLLISION_CAUSES, OFFROAD_CAUSES

KINDS = ("onramp", "onramp", "roundabout", None)


def toy_windows():
    """Toy scenes: three named as synthesized windows (two on-ramps, one roundabout), one as a real scene."""
    return [
        make_scenario(5, scenario_id=synth_window_id(kind, 7, 0, n) if kind else f"scene-{n}", seed=n)
        for n, kind in enumerate(KINDS)
    ]


def write_windows(folder):
    scenes = toy_windows()
    source = folder / "scenes.tfrecord"
    write_scenarios(source, scenes)
    labels = folder / "labels"
    (labels / "labels").mkdir(parents=True)
    records = [make_record(s, source=str(source.resolve()), record=n) for n, s in enumerate(scenes)]
    write_shard(labels / "labels" / "0000-scenes.jsonl", records)
    write_manifest(labels, {"format_version": 1, "shards": [{"file": "labels/0000-scenes.jsonl"}]})
    return labels


def assert_parts_sum(row):
    offroad = sum(row[f"offroad:{c}"] for c in OFFROAD_CAUSES[1:])
    assert (math.isnan(row["offroad"]) and math.isnan(offroad)) or offroad == pytest.approx(row["offroad"])
    assert sum(row[f"collision:{c}"] for c in COLLISION_CAUSES) == pytest.approx(row["collision"])


def test_the_window_kind_is_the_synthesized_network_kind_or_the_dataset():
    assert [window_kind(s, "toy") for s in toy_windows()] == ["onramp", "onramp", "roundabout", "toy"]
    scene = make_scenario(3, scenario_id="x")
    assert window_kind(replace(scene, metadata={"kind": "city"}), "toy") == "city"


def test_the_failures_table_sorts_every_event_by_cause(tmp_path, capsys):
    labels = write_windows(tmp_path)
    out = tmp_path / "failures.json"
    args = ["experiment", "failures", "--data", f"toy={labels}:all:2", "--method", "cv=constant_velocity",
            "--method", "still=stationary", "--json", str(out)]  # fmt: skip
    assert main(args) == 0
    printed = capsys.readouterr().out
    assert "| cv |" in printed and f"| {LOG_ROW} |" in printed and "by network kind" in printed
    result = json.loads(out.read_text())["toy"]
    assert set(result["table"]) == {"cv", "still", LOG_ROW}
    assert set(result["by_kind"]) == {"onramp", "roundabout", "toy"}
    assert result["by_kind"]["onramp"]["cv"]["windows"] == 2
    for row in [*result["table"].values(), *(r for per in result["by_kind"].values() for r in per.values())]:
        assert set(BREAKDOWN_KEYS) <= set(row)
        assert_parts_sum(row)
    windows = result["per_window"]["cv"]
    assert [w["kind"] for w in windows] == ["onramp", "onramp", "roundabout", "toy"]
    events = [e for w in windows for e in w["events"]]
    assert events and all(e["cause"] in (*OFFROAD_CAUSES, *COLLISION_CAUSES) for e in events)
    assert result["table"]["still"]["collision:other"] == 0.0  # standing still hits nobody new
    assert main([*args[:-2], "--no-floor"]) == 0
    assert LOG_ROW not in capsys.readouterr().out


def test_the_log_row_name_is_reserved():
    with pytest.raises(InputError, match="log's own row"):
        experiment_settings("failures", None, {"datasets": ["a=b"], "methods": [f"{LOG_ROW}=stationary"]})


def test_the_realism_table_breaks_its_rates_down_by_cause():
    scenes = toy_windows()[:2]
    methods = [Method("cv", baseline="constant_velocity"), Method("still", baseline="stationary")]
    result = realism_table(methods, scenes, SimConfig(rollouts=2), 2, 2, {"cv": None, "still": None})
    for name in ("cv", "still"):
        assert_parts_sum(result["table"][name])
        for row in result["per_window"][name]:
            assert_parts_sum(row)
    text = breakdown_markdown(result["table"])
    assert text.splitlines()[0].startswith("| method | offroad | offroad:map ends |") and "| cv |" in text
