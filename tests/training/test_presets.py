"""Every preset and recipe in configs/ loads, and the GPU presets carry the memory settings that make them
fit (docs/model.md, 'Training memory'; docs/benchmarks.md, 'Training memory (issue 28, 2026-11-26)')."""

from __future__ import annotations

from pathlib import Path

import pytest

from langtraj.training.config import load_config
from langtraj.training.recipe import load_recipe

ROOT = Path(__file__).resolve().parents[2]
PRESETS = sorted((ROOT / "configs").glob("*.yaml"))
RECIPES = sorted((ROOT / "configs" / "recipes").glob("*.yaml"))


@pytest.mark.parametrize("path", PRESETS, ids=lambda p: p.stem)
def test_every_preset_loads(path):
    config = load_config(path)
    assert config.stage == (2 if config.model.use_text else 1)


@pytest.mark.parametrize("path", RECIPES, ids=lambda p: p.stem)
def test_every_recipe_loads(path):
    recipe = load_recipe(path)
    assert recipe.stages and recipe.name == path.stem


@pytest.mark.parametrize("name", ["base", "base-ddp", "base-text", "base-distill", "base-closed-loop"])
def test_the_base_presets_train_in_bf16_with_gradient_checkpointing(name):
    config = load_config(ROOT / "configs" / f"{name}.yaml")
    assert config.precision == "bf16-mixed" and config.model.gradient_checkpointing


def test_the_gpu_short_preset_is_the_middle_sized_model():
    config = load_config(ROOT / "configs" / "gpu-short.yaml")
    model, data = config.model, config.data
    assert (model.hidden_dim, model.encoder_layers, model.denoiser_blocks) == (128, 2, 3)
    assert (data.max_agents, data.max_polylines, data.points_per_polyline) == (32, 128, 10)
    assert (config.batch_size, config.precision, config.accelerator, config.stage) == (64, "bf16-mixed", "gpu", 1)
    assert not model.gradient_checkpointing  # 7.7 GiB without it: recomputing would only cost time


def test_the_gpu_short_recipe_distills_its_stage_one_and_ships_the_result():
    recipe = load_recipe(ROOT / "configs" / "recipes" / "gpu-short.yaml")
    assert [s.name for s in recipe.stages] == ["stage1", "distill"] and recipe.shipped_stage == "distill"
    stage1, distill = (load_config(recipe.folder / s.config) for s in recipe.stages)
    assert distill.model.diffusion_steps == 5 and distill.model.hidden_dim == stage1.model.hidden_dim
    assert stage1.max_steps == 4000 and distill.max_steps < stage1.max_steps / 4
