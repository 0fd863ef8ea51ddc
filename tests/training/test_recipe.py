"""`langtraj recipe`: the whole chain (synthesis, labels, stage 1, stage 2, distillation, closed-loop
training) on a toy corpus; a second run skips every finished step, a killed stage resumes."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml
from dataset_builders import TINY_TRAINING

from langtraj.cli.main import main
from langtraj.errors import InputError
from langtraj.model.checkpoint import load_model
from langtraj.training.recipe import load_recipe

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
    _write(
        tmp_path,
        "recipe.yaml",
        {
            "name": "toy",
            "corpus": {"kinds": "signalized", "windows": 2, "seed": 3},
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
    assert set(record["seconds"]) == {"corpus", "labels", "s1", "s2", "distill", "cl"}
    assert record["shipped"] == str(out / "distill" / "checkpoints" / "last.ckpt")  # the stage it ships
    assert "shipped checkpoint (distill)" in printed
    # a second run skips what is done; a stage whose marker is gone resumes from its checkpoint
    (out / "cl" / "DONE.json").unlink()
    assert main(["recipe", str(recipe_file), "--out", str(out), "--workers", "1"]) == 0
    printed = capsys.readouterr().out
    assert printed.count("skipped") == 5 and "cl: " in printed


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
