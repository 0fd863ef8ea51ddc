"""`langtraj recipe`: the whole chain (synthesis, labels, stage 1, stage 2, distillation, closed-loop
training) on a toy corpus; a second run skips every finished step, a killed stage resumes."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml
from dataset_builders import TINY_TRAINING

from langtraj.cli.main import main
from langtraj.errors import InputError
from langtraj.model.checkpoint import load_model
from langtraj.training.recipe import corpus_shards, load_recipe

SMALL = {
    **{k: v for k, v in TINY_TRAINING.items() if k not in ("name", "stage")},
    "batch_size": 2,
    "data": {**TINY_TRAINING["data"], "max_polylines": 16},
    "val": {"sample_steps": 5, "wosac_scenes": 0, "max_batches": 1},
}
"""The tests' tiny training settings, with validation a 5-step model can run."""


def _write(folder: Path, name: str, data: dict) -> None:
    (folder / name).write_text(yaml.safe_dump(data))


@pytest.fixture()
def recipe_file(tmp_path) -> Path:
    _write(tmp_path, "s1.yaml", {**SMALL, "stage": 1, "model": {**SMALL["model"], "use_text": False}})
    _write(tmp_path, "s2.yaml", {"extends": "s1.yaml", "stage": 2, "model": {"use_text": True}})
    _write(tmp_path, "distill.yaml", {"extends": "s2.yaml", "model": {"diffusion_steps": 5}})
    _write(
        tmp_path,
        "cl.yaml",
        {"extends": "distill.yaml", "objective": "closed_loop", "model": {"num_actions": 8},
         "closed_loop": {"candidates": 2}},
    )  # fmt: skip
    stages = [{"name": n, "config": f"{n}.yaml"} for n in ("s1", "s2", "distill", "cl")]
    stages[0]["data"] = "corpus"  # stage 1 reads every corpus window, without labels
    _write(
        tmp_path,
        "recipe.yaml",
        {
            "name": "toy",
            "corpus": {"kinds": "signalized", "windows": 2, "seed": 3},
            "labels": {"windows": 1},
            "stages": stages,
            "ship": "distill",
        },
    )
    return tmp_path / "recipe.yaml"


def test_the_recipe_runs_every_stage_then_skips_them(recipe_file, tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["recipe", str(recipe_file), "--out", str(out), "--workers", "1"]) == 0
    printed = capsys.readouterr().out
    for step in ("corpus", "labels", "s1", "s2", "distill", "cl"):
        assert f"{step}: " in printed and (out / step / "DONE.json").is_file()
    model, data = load_model(out / "cl" / "checkpoints" / "last.ckpt")
    assert (model.config.diffusion_steps, model.config.num_actions) == (5, 8) and data.map_selection == "agents"
    record = json.loads((out / "recipe.json").read_text())
    features = {"features s1", "features s2"}  # the later stages read stage 2's store (same sample settings)
    assert set(record["seconds"]) == {"corpus", "labels", "s1", "s2", "distill", "cl"} | features
    (corpus_store,) = (out / "features").iterdir()  # stage 1's store of the unlabelled corpus
    assert corpus_store.name.startswith("corpus-") and (corpus_store / "store.json").is_file()
    assert len(list((out / "labels" / "features").iterdir())) == 1  # later stages share one sample config
    assert record["shipped"] == str(out / "distill" / "checkpoints" / "last.ckpt")  # the stage it ships
    assert "shipped checkpoint (distill)" in printed
    # a second run skips what is done; a stage whose marker is gone resumes from its checkpoint
    (out / "cl" / "DONE.json").unlink()
    assert main(["recipe", str(recipe_file), "--out", str(out), "--workers", "1"]) == 0
    printed = capsys.readouterr().out
    assert printed.count("skipped") == 5 and "cl: " in printed
    assert "resuming from" in printed and "input: feature store" in printed  # cl reads its labels' store
    assert not [line for line in printed.splitlines() if line.startswith("feature")]  # no store built again


def test_the_label_subset_takes_whole_shards_from_every_kind_in_turn(tmp_path):
    shards = [("a", 0, 40), ("a", 1, 40), ("a", 2, 40), ("b", 0, 30), ("b", 1, 0), ("b", 2, 30), ("c", 0, 10)]
    manifest = {"shards": [{"file": f"shards/{k}-{i:04d}.tfrecord", "kind": k, "windows": w} for k, i, w in shards]}
    (tmp_path / "manifest.json").write_text(json.dumps(manifest))
    names = lambda paths: [p.name for p in paths]  # noqa: E731
    assert names(corpus_shards(tmp_path, 75)) == ["a-0000.tfrecord", "b-0000.tfrecord", "c-0000.tfrecord"]
    assert names(corpus_shards(tmp_path, 81)) == [
        "a-0000.tfrecord", "a-0001.tfrecord", "b-0000.tfrecord", "c-0000.tfrecord"
    ]  # fmt: skip
    assert len(corpus_shards(tmp_path, None)) == 6  # every shard with windows
    stages = [{"name": "s", "config": "s.yaml"}]
    with pytest.raises(InputError, match=r"labels\.windows"):
        load_recipe_text(tmp_path, {"name": "x", "labels": {"windows": 0}, "stages": stages})


def load_recipe_text(folder: Path, data: dict):
    _write(folder, "s.yaml", {**SMALL, "stage": 1})
    _write(folder, "r.yaml", data)
    return load_recipe(folder / "r.yaml")


# Slow (1 min); `pytest -m slow`. A killed `train` resuming is tests/cli/test_train_and_sample.py's.
@pytest.mark.slow
def test_a_killed_recipe_resumes_its_stage_from_the_last_checkpoint(recipe_file, tmp_path):
    """SIGKILL in the middle of stage 1, then the same command: it goes on from the checkpoint it had."""
    data = yaml.safe_load(recipe_file.read_text())
    _write(recipe_file.parent, "long.yaml", {"extends": "s1.yaml", "max_steps": 400})
    data["stages"] = [{"name": "s1", "config": "long.yaml", "data": "corpus"}]
    data.pop("ship")
    _write(recipe_file.parent, "kill.yaml", data)
    out = tmp_path / "run"
    command = [sys.executable, "-m", "langtraj.cli.main", "recipe", str(recipe_file.parent / "kill.yaml")]
    job = subprocess.Popen([*command, "--out", str(out), "--workers", "1"], stdout=subprocess.DEVNULL)
    deadline = time.monotonic() + 300
    while len(list((out / "s1" / "checkpoints").glob("step*.ckpt"))) < 2:
        assert job.poll() is None and time.monotonic() < deadline, "the recipe ended or stalled before stage 1"
        time.sleep(0.2)
    job.send_signal(signal.SIGKILL)
    job.wait()
    assert not (out / "s1" / "DONE.json").exists()
    before = load_model(out / "s1" / "checkpoints" / "last.ckpt")  # a kill never leaves a half-written file
    assert before is not None
    again = subprocess.run([*command, "--out", str(out), "--workers", "1", "--max-steps", "6"], capture_output=True)
    printed = again.stdout.decode()
    assert again.returncode == 0, again.stderr.decode()[-2000:]
    assert "corpus: done before" in printed and "resuming from" in printed
    step = int(printed.split("resuming from")[1].split("(step ")[1].split(")")[0])
    assert step >= 1 and (out / "s1" / "DONE.json").is_file()


def test_a_bad_recipe_is_one_line(recipe_file, tmp_path):
    data = yaml.safe_load(recipe_file.read_text())
    data["stages"][1]["config"] = "missing.yaml"
    _write(tmp_path, "bad.yaml", data)
    with pytest.raises(InputError, match="no such file"):
        load_recipe(tmp_path / "bad.yaml")
    assert main(["recipe", "no-such-recipe", "--out", str(tmp_path / "x")]) == 2
    _write(tmp_path, "ship.yaml", {**yaml.safe_load(recipe_file.read_text()), "ship": "stage9"})
    with pytest.raises(InputError, match="'stage9' is not a stage"):
        load_recipe(tmp_path / "ship.yaml")
