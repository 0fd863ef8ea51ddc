"""The dataset builder, the InterDrive JSON exchange, stats and the `langtraj interdrive` verbs."""

from __future__ import annotations

import json
import shutil
from collections import Counter
from pathlib import Path

import pytest

from langtraj.cli.main import main
from langtraj.interdrive.dataset import BuildConfig, build_dataset, iter_records, read_manifest
from langtraj.interdrive.exchange import export_json, import_json, records_by_id
from langtraj.interdrive.labels import LabelSource
from langtraj.interdrive.stats import dataset_stats, format_stats
from langtraj.synth.factory import FactoryConfig, run_factory
from langtraj.synth.shard import ShardConfig
from langtraj.synth.windows import WindowConfig


@pytest.fixture(scope="module")
def corpus(tmp_path_factory) -> list[Path]:
    """Two small synthesized shards (SUMO events included)."""
    out = tmp_path_factory.mktemp("corpus")
    short = ShardConfig(duration_s=110.0, window=WindowConfig(warmup_s=40.0))
    config = FactoryConfig(
        kinds=("signalized", "onramp"), windows=4, seed=11, out=out, workers=1, windows_per_shard=2, shard=short
    )
    manifest = run_factory(config, progress=False)
    return [out / s["file"] for s in manifest["shards"]]


@pytest.fixture(scope="module")
def dataset(corpus, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("interdrive") / "ds"
    build_dataset(corpus, out, BuildConfig(seed=3))
    return out


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_build_writes_a_shard_per_file_and_a_manifest_that_counts_them(corpus, dataset):
    manifest = read_manifest(dataset)
    assert [Path(s["source"]) for s in manifest["shards"]] == [p.resolve() for p in corpus]
    total = 0
    for shard, (_, records) in zip(manifest["shards"], iter_records(dataset), strict=True):
        assert shard["windows"] == len(records) > 0
        total += len(records)
        for rec in records:
            assert rec.num_steps == 91 and rec.current_index == 10
            assert {lab.track_id for lab in rec.labels.agent_labels} <= set(rec.track_ids)
            for inter in rec.labels.interactions:
                assert inter.track_id in rec.track_ids
                assert inter.other_id == -1 or inter.other_id in rec.track_ids
            for prompt in rec.prompts:
                assert set(prompt.roles) == set(prompt.mentions)
                assert all("the target agent" in sentence for sentence in prompt.roles.values())
    assert manifest["windows"] == total
    sources = {i.source for _, recs in iter_records(dataset) for r in recs for i in r.labels.interactions}
    assert LabelSource.GROUND_TRUTH in sources  # synthesized scenes carry SUMO events


def test_rebuild_reuses_shards_and_a_new_seed_redraws_prompts(corpus, dataset, tmp_path):
    copy = tmp_path / "ds"
    shutil.copytree(dataset, copy)
    before = _snapshot(copy)
    build_dataset(corpus, copy, BuildConfig(seed=3))
    assert _snapshot(copy) == before
    build_dataset(corpus, copy, BuildConfig(seed=4))
    after = _snapshot(copy)
    changed = [k for k in before if k.startswith("labels/") and before[k] != after[k]]
    assert changed  # prompts are drawn anew; labels stay
    old = records_by_id(dataset)
    for sid, rec in records_by_id(copy).items():
        assert rec.labels == old[sid].labels


def test_export_then_import_round_trips_as_human_labels(corpus, dataset, tmp_path):
    ds = tmp_path / "ds"
    shutil.copytree(dataset, ds)
    first = tmp_path / "json1"
    summary = export_json(ds, first)
    files = sorted(first.glob("*.json"))
    assert summary.written == len(files) > 0
    doc = json.loads(files[0].read_text())
    fields = {"track_id", "interact_with_other_agent", "interaction_type", "interaction_subtype"}
    for key in ("agent_0", "agent_1"):
        assert set(doc[key]) == fields | {"no_behavior_description"}
    assert import_json(first, ds) == len(files)
    records = records_by_id(ds)
    for path in files:
        doc = json.loads(path.read_text())
        rec = records[doc["scenario_id"]]
        human = [i for i in rec.labels.interactions if i.source is LabelSource.HUMAN]
        assert {(i.track_id, i.other_id) for i in human} == {
            (doc["agent_0"]["track_id"], doc["agent_1"]["track_id"]),
            (doc["agent_1"]["track_id"], doc["agent_0"]["track_id"]),
        }
    second = tmp_path / "json2"
    export_json(ds, second)
    assert _snapshot(first) == _snapshot(second)
    assert import_json(second, ds) == len(files)  # importing again is idempotent
    assert records_by_id(ds) == records
    build_dataset(corpus, ds, BuildConfig(seed=9))  # a rebuild with other settings keeps the human labels
    for sid, rec in records_by_id(ds).items():
        human = {i for i in rec.labels.interactions if i.source is LabelSource.HUMAN}
        assert human == {i for i in records[sid].labels.interactions if i.source is LabelSource.HUMAN}


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda d: d.update(scenario_id="nope"), "no window 'nope'"),
        (lambda d: d["agent_0"].update(track_id=987654), "track 987654 is not in window"),
        (lambda d: d["agent_1"].update(interaction_subtype="Flying"), "unknown"),
        (lambda d: d["agent_0"].update(interaction_type="Teleporting"), "unknown interaction type"),
        (lambda d: d["agent_0"].pop("interact_with_other_agent"), "missing field 'interact_with_other_agent'"),
    ],
)
def test_bad_import_names_the_file_and_changes_nothing(dataset, tmp_path, capsys, edit, message):
    ds = tmp_path / "ds"
    shutil.copytree(dataset, ds)
    json_dir = tmp_path / "json"
    export_json(ds, json_dir)
    path = sorted(json_dir.glob("*.json"))[-1]
    doc = json.loads(path.read_text())
    edit(doc)
    path.write_text(json.dumps(doc))
    before = _snapshot(ds)
    assert main(["interdrive", "import", str(json_dir), "--into", str(ds)]) == 2
    err = capsys.readouterr().err
    assert str(path) in err and message in err
    assert _snapshot(ds) == before


def test_import_rejects_malformed_json(dataset, tmp_path, capsys):
    json_dir = tmp_path / "json"
    json_dir.mkdir()
    (json_dir / "x.json").write_text("{not json")
    assert main(["interdrive", "import", str(json_dir), "--into", str(dataset)]) == 2
    assert "x.json: not JSON" in capsys.readouterr().err


def test_stats_prints_counts_and_plots_them(dataset, tmp_path, capsys):
    stats = dataset_stats(dataset)
    per_source = [stats.by_subtype(src) for src in stats.sources()]
    assert len(per_source) >= 2 and stats.by_subtype() == sum(per_source, Counter())
    table = format_stats(stats)
    assert f"{stats.windows} windows" in table and "Yielding" in table and "changing lanes" in table
    plot = tmp_path / "fig2.png"
    assert main(["interdrive", "stats", str(dataset), "--plot", str(plot)]) == 0
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "Following/Stopping Behind" in capsys.readouterr().out


def test_cli_build_and_bad_input(corpus, tmp_path, capsys):
    out = tmp_path / "ds"
    assert main(["interdrive", "build", str(corpus[0]), "--out", str(out), "--prompts-per-agent", "2"]) == 0
    assert "windows" in capsys.readouterr().out
    assert main(["interdrive", "build", str(tmp_path / "missing.tfrecord"), "--out", str(tmp_path / "x")]) == 2
    assert "missing.tfrecord: no such scenario file" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()
    assert main(["interdrive", "stats", str(tmp_path)]) == 2
    assert "not an InterDrive dataset folder" in capsys.readouterr().err
    truncated = tmp_path / "cut.tfrecord"
    truncated.write_bytes(corpus[0].read_bytes()[:1000])
    assert main(["interdrive", "build", str(truncated), "--out", str(tmp_path / "y")]) == 2
    assert "cut.tfrecord" in capsys.readouterr().err
    assert not (tmp_path / "y" / "manifest.json").exists()


def test_show_renders_a_window_with_its_labels(dataset, tmp_path, capsys):
    record = next(r for _, recs in iter_records(dataset) for r in recs if r.labels.interactions)
    out = tmp_path / "show.png"
    assert main(["interdrive", "show", str(dataset), record.scenario_id, "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert record.scenario_id in text and "Interactions" in text and "as @" in text
    assert main(["interdrive", "show", str(dataset), "nope", "--out", str(out)]) == 2
    assert "no window 'nope'" in capsys.readouterr().err
    assert main(["interdrive", "show", str(dataset), record.scenario_id, "--out", str(out), "--agents", "99999"]) == 2
    assert "track 99999 is not in this window" in capsys.readouterr().err


def test_an_unreachable_llm_endpoint_fails_before_anything_is_written(corpus, tmp_path, capsys):
    out = tmp_path / "d"
    args = ["interdrive", "build", str(corpus[0]), "--out", str(out), "--llm-url", "http://127.0.0.1:9/v1"]
    assert main(args) == 2
    assert "127.0.0.1:9" in capsys.readouterr().err
    assert not (out / "manifest.json").exists()


def test_build_refuses_a_file_listed_twice(corpus, tmp_path, capsys):
    assert main(["interdrive", "build", str(corpus[0]), str(corpus[0]), "--out", str(tmp_path / "d")]) == 2
    assert "listed twice" in capsys.readouterr().err


@pytest.mark.real_data
def test_build_on_real_scenes_windows_nuscenes_and_uses_the_detector(real_data_dir, tmp_path):
    files = [
        real_data_dir / "motion_data_one_scenario.tfrecord",
        real_data_dir / "sd_nuscenes_v1.0-mini_scene-0061.pkl",
    ]
    manifest = build_dataset(files, tmp_path / "ds", BuildConfig())
    womd, nuscenes = (read_shard_records for _, read_shard_records in iter_records(tmp_path / "ds"))
    assert len(womd) == 1 and womd[0].scenario_id == "637f20cafde22ff8"
    assert len(nuscenes) >= 2 and all(r.scenario_id.endswith(f"_w{r.window_start}") for r in nuscenes)
    assert manifest["windows"] == len(womd) + len(nuscenes)
    for rec in womd + nuscenes:
        assert all(i.source is LabelSource.DETECTOR for i in rec.labels.interactions)
        assert rec.labels.agent_labels
    assert any(r.labels.undecided for r in nuscenes)  # nuScenes maps lack road edges and neighbours
