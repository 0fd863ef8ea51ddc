"""The factory end to end: shards, manifest, determinism, resume, every kind, and the CLI."""

from __future__ import annotations

import json
import shutil
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np
import pytest
from scenario_builders import make_scenario

from langtraj.cli.main import main
from langtraj.fileio import ZSTD_MAGIC
from langtraj.scenario.io import read_scenarios, write_scenarios
from langtraj.scenario.io.tfrecord import count_records
from langtraj.scenario.types import AgentType
from langtraj.synth import factory
from langtraj.synth.factory import FactoryConfig, run_factory, shard_path
from langtraj.synth.network import kind_names
from langtraj.synth.shard import ShardConfig, ShardOutcome, ShardTask, run_shard, shard_seed
from langtraj.synth.windows import WindowConfig

SHORT = ShardConfig(duration_s=100.0, window=WindowConfig(warmup_s=40.0))


def _config(out: Path, workers: int = 1) -> FactoryConfig:
    return FactoryConfig(
        kinds=("signalized",), windows=3, seed=7, out=out, workers=workers, windows_per_shard=2, shard=SHORT
    )


@pytest.fixture(scope="module")
def first_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("synth") / "a"
    return out, run_factory(_config(out), progress=False)


def test_manifest_counts_what_the_shards_hold(first_run):
    out, manifest = first_run
    on_disk = json.loads((out / "manifest.json").read_text())
    assert on_disk == manifest
    stats = manifest["per_kind"]["signalized"]
    assert stats["windows"] == manifest["windows"] == 3
    assert manifest["sumo_version"].startswith("SUMO 1.28")
    total = 0
    for shard in manifest["shards"]:
        path = out / shard["file"]
        assert count_records(path) == shard["windows"]
        assert shard["seed"] == shard_seed(7, "signalized", shard["index"])
        total += shard["windows"]
    assert total == 3
    assert stats["agents_per_window"]["min"] >= 10
    assert sum(stats["events"].values()) > 0


def test_windows_read_back_with_the_womd_reader(first_run):
    out, manifest = first_run
    scenarios = [s for shard in manifest["shards"] for s in read_scenarios(out / shard["file"])]
    assert len({s.scenario_id for s in scenarios}) == 3
    for s in scenarios:
        assert s.num_steps == 91 and s.current_index == 10
        assert 10 <= s.num_agents <= 128
        assert s.agents.valid[s.sdc_index].all()
        assert len(s.agents.objects_of_interest) >= 1
        assert s.road_map.lanes and s.traffic_lights.lane_ids.size > 0
        assert s.metadata["kind"] == "signalized"
        ids = set(s.agents.ids.tolist())
        assert all(e.track_id in ids and (e.other_id == -1 or e.other_id in ids) for e in s.events)
        assert all(0 <= e.start < e.end <= 91 for e in s.events)


def test_same_seed_gives_byte_identical_shards_whatever_the_workers(first_run, tmp_path):
    out, manifest = first_run
    again = run_factory(_config(tmp_path / "b", workers=2), progress=False)
    assert [s["file"] for s in again["shards"]] == [s["file"] for s in manifest["shards"]]
    for shard in manifest["shards"]:
        assert (out / shard["file"]).read_bytes() == (tmp_path / "b" / shard["file"]).read_bytes()


def test_rerun_resumes_without_simulating(first_run, monkeypatch):
    out, manifest = first_run

    def refuse(*args, **kwargs):
        raise AssertionError("a finished shard was run again")

    monkeypatch.setattr(factory, "run_shard", refuse)
    assert run_factory(_config(out), progress=False)["shards"] == manifest["shards"]


def test_a_damaged_sidecar_makes_the_shard_run_again(first_run, tmp_path):
    out, manifest = first_run
    copy = tmp_path / "c"
    shutil.copytree(out / "shards", copy / "shards")
    first = manifest["shards"][0]["file"]
    sidecar = (copy / first).parent / "signalized-0000.json"
    sidecar.write_text("{not json")
    stale = copy / "shards" / "signalized-0000.tfrecord"  # as an earlier run with --no-compress left it
    stale.write_bytes(b"stale")
    run_factory(_config(copy), progress=False)
    assert (copy / first).read_bytes() == (out / first).read_bytes()
    assert json.loads(sidecar.read_text())["windows"] == manifest["shards"][0]["windows"]
    assert not stale.exists()  # a shard that runs again replaces its file under either name


def test_shards_are_compressed_by_default(first_run):
    out, manifest = first_run
    for shard in manifest["shards"]:
        path = out / shard["file"]
        assert shard["file"] == f"shards/signalized-{shard['index']:04d}.tfrecord.zst"
        assert path.read_bytes()[:4] == ZSTD_MAGIC
        assert shard["bytes"] == path.stat().st_size
        sidecar = json.loads((path.parent / f"signalized-{shard['index']:04d}.json").read_text())
        assert (sidecar["file"], sidecar["bytes"]) == (path.name, shard["bytes"])
    stats = manifest["per_kind"]["signalized"]
    assert stats["bytes_per_window"] == round(sum(s["bytes"] for s in manifest["shards"]) / stats["windows"])


def test_shard_names_with_and_without_compression_share_the_sidecar(tmp_path):
    assert shard_path(tmp_path, "zebra", 7) == tmp_path / "shards" / "zebra-0007.tfrecord.zst"
    assert shard_path(tmp_path, "zebra", 7, compress=False) == tmp_path / "shards" / "zebra-0007.tfrecord"
    for compress in (True, False):
        task = ShardTask("zebra", 7, 1, 2, shard_path(tmp_path, "zebra", 7, compress))
        assert task.stats_path == tmp_path / "shards" / "zebra-0007.json"
        assert task.other_path == shard_path(tmp_path, "zebra", 7, not compress)


def _finished_shard(out: Path, compress: bool, *, old_sidecar: bool = False) -> ShardTask:
    """A shard file and sidecar as a finished shard (index 0 of `_config`) leaves them, without SUMO;
    `old_sidecar` drops the fields that sidecars written before compression lack."""
    task = ShardTask("signalized", 0, shard_seed(7, "signalized", 0), 2, shard_path(out, "signalized", 0, compress))
    write_scenarios(task.path, [make_scenario(scenario_id="w0"), make_scenario(scenario_id="w1", seed=1)])
    outcome = ShardOutcome(
        kind=task.kind,
        index=task.index,
        seed=task.seed,
        quota=task.quota,
        settings=asdict(SHORT),
        windows=2,
        agents_per_window=[4, 4],
        agent_types={"vehicle": 8},
        events={},
        rejections={},
        collisions=0,
        teleports=0,
        network={},
        demand={},
        sumo_version="SUMO 1.28.0",
        seconds=1.0,
        file=task.path.name,
        bytes=task.path.stat().st_size,
    )
    data = asdict(outcome)
    if old_sidecar:
        del data["file"], data["bytes"]
    task.stats_path.write_text(json.dumps(data))
    return task


@pytest.mark.parametrize("written", [True, False], ids=["written-compressed", "written-plain"])
@pytest.mark.parametrize("compress", [True, False], ids=["resumed-compressed", "resumed-plain"])
def test_resume_takes_a_finished_shard_under_either_name(written, compress, tmp_path, monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError("a finished shard was run again")

    monkeypatch.setattr(factory, "run_shard", refuse)
    done = _finished_shard(tmp_path, written, old_sidecar=not written)
    config = replace(_config(tmp_path), windows=2, compress=compress)
    manifest = run_factory(config, progress=False)
    (shard,) = manifest["shards"]
    assert shard["file"] == f"shards/{done.path.name}" and shard["bytes"] == done.path.stat().st_size
    assert manifest["per_kind"]["signalized"]["bytes_per_window"] == round(shard["bytes"] / 2)


def test_resume_prefers_the_configured_name_and_needs_a_shard_file(tmp_path):
    plain = _finished_shard(tmp_path, compress=False)
    packed = _finished_shard(tmp_path, compress=True)
    for task in (plain, packed):
        assert factory._finished(task, SHORT).file == task.path.name
    plain.path.unlink()
    packed.path.unlink()
    assert factory._finished(packed, SHORT) is None


def test_cli_no_compress_turns_compression_off(tmp_path, monkeypatch, capsys):
    seen = []

    def fake(config, progress=True):
        seen.append(config.compress)
        return {"per_kind": {}, "windows": 0}

    monkeypatch.setattr(factory, "run_factory", fake)
    for extra in ([], ["--no-compress"]):
        assert main(["synth", "--kinds", "zebra", "--windows", "1", "--out", str(tmp_path), *extra]) == 0
    assert seen == [True, False]


@pytest.mark.parametrize("kind", kind_names())
def test_every_kind_makes_a_window_that_reads_back_and_renders(kind, tmp_path):
    from langtraj.viz import save_png

    task = ShardTask(kind, 0, shard_seed(3, kind, 0), 1, tmp_path / f"{kind}.tfrecord")
    outcome = run_shard(task, SHORT)
    assert outcome.windows == 1, outcome.rejections
    (scenario,) = read_scenarios(task.path)
    assert np.isfinite(scenario.agents.states[scenario.agents.valid]).all()
    assert scenario.agents.type_counts()["vehicle"] >= 1
    save_png(scenario, scenario.current_index, tmp_path / f"{kind}.png")
    assert (tmp_path / f"{kind}.png").stat().st_size > 1000


def test_pedestrians_and_cyclists_appear(first_run):
    out, manifest = first_run
    types = manifest["per_kind"]["signalized"]["agent_types"]
    assert types["pedestrian"] > 0 and types["cyclist"] > 0
    scenarios = [s for shard in manifest["shards"] for s in read_scenarios(out / shard["file"])]
    assert any((s.agents.types == AgentType.PEDESTRIAN).any() for s in scenarios)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--kinds", "motorway"], "unknown scenario kind 'motorway'"),
        (["--kinds", ","], "no scenario kind given"),
        (["--windows", "0"], "--windows: must be at least 1"),
        (["--workers", "0"], "--workers: must be at least 1"),
        (["--duration", "5"], "--duration: must be within"),
    ],
)
def test_cli_rejects_bad_arguments(args, message, tmp_path, capsys):
    assert main(["synth", "--out", str(tmp_path / "o"), *args]) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_cli_lists_the_kinds(capsys):
    assert main(["synth", "--list-kinds"]) == 0
    listed = [line.split()[0] for line in capsys.readouterr().out.splitlines()]
    assert listed == list(kind_names())


def test_a_shard_made_with_other_settings_is_not_reused(first_run):
    out, manifest = first_run
    shard = manifest["shards"][0]
    task = ShardTask("signalized", shard["index"], shard["seed"], 2, out / shard["file"])
    assert factory._finished(task, SHORT) is not None
    assert factory._finished(task, ShardConfig(duration_s=120.0, window=SHORT.window)) is None
    assert factory._finished(ShardTask(task.kind, task.index, task.seed + 1, 2, task.path), SHORT) is None


def test_automatic_duration_fits_the_quota_to_the_centres():
    auto = ShardConfig()
    one_centre = auto.duration_for(40, 1)
    assert one_centre == pytest.approx(60.0 + 40 * 9.1 * 1.6)
    assert auto.duration_for(40, 6) == pytest.approx(60.0 + 7 * 9.1 * 1.6, abs=0.05)
    assert auto.duration_for(4, 8) == 150.0  # the lower bound
    assert auto.duration_for(400, 1) == 900.0  # the upper bound
    assert ShardConfig(duration_s=100.0).duration_for(40, 1) == 100.0


def test_an_output_path_that_is_a_file_fails_before_simulating(tmp_path, monkeypatch, capsys):
    def refuse(*args, **kwargs):
        raise AssertionError("simulated although the output cannot be written")

    monkeypatch.setattr(factory, "run_shard", refuse)
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert main(["synth", "--kinds", "zebra", "--windows", "1", "--out", str(blocker), "--no-progress"]) == 1
    assert "Not a directory" in capsys.readouterr().err


def test_ray_executor_writes_the_same_shards(first_run, tmp_path):
    pytest.importorskip("ray", reason="Ray is optional: pip install 'langtraj[ray]'")
    import ray

    out, manifest = first_run
    config = _config(tmp_path / "ray", workers=2)
    try:
        again = run_factory(replace(config, executor="ray"), progress=False)
    finally:
        ray.shutdown()
    assert again["shards"] == manifest["shards"]
    for shard in manifest["shards"]:
        assert (out / shard["file"]).read_bytes() == (tmp_path / "ray" / shard["file"]).read_bytes()


def test_ray_executor_without_ray_says_how_to_install_it(monkeypatch):
    import sys

    from langtraj.errors import LangTrajError
    from langtraj.executors import EXECUTORS

    monkeypatch.setitem(sys.modules, "ray", None)  # import ray now raises ImportError
    with pytest.raises(LangTrajError, match=r"pip install 'langtraj\[ray\]'"):
        list(EXECUTORS.create("ray").map(len, ["a"], 1))
