"""Small InterDrive datasets on disk for training tests: toy scenes with hand-made prompts."""

from __future__ import annotations

from pathlib import Path

from scenario_builders import make_scenario

from langtraj.interdrive.dataset import PromptEntry, WindowRecord, write_manifest, write_shard
from langtraj.interdrive.labels import WindowLabels
from langtraj.scenario import Scenario
from langtraj.scenario.io import write_scenarios


def make_prompt(mentions: tuple[int, ...], subtype: str | None = None) -> PromptEntry:
    text = " and ".join(f"@{m}" for m in mentions) + (" interact" if subtype else " drives")
    roles = {m: f"the target agent {subtype or 'label'} of {m}" for m in mentions}
    return PromptEntry(text, mentions, roles, subtype, ("cruise",) if subtype is None else (), "heuristic")


def make_record(scenario: Scenario, prompts=(), source: str = "none", record: int = 0) -> WindowRecord:
    return WindowRecord(
        scenario.scenario_id,
        source,
        record,
        0,
        scenario.current_index,
        scenario.num_steps,
        tuple(int(i) for i in scenario.agents.ids),
        WindowLabels(scenario.scenario_id),
        tuple(prompts),
    )


def write_dataset(folder: Path, num_scenes: int = 24) -> Path:
    """A scenario file of `num_scenes` small scenes and a labels folder whose even scenes have an
    interaction prompt and odd ones single-agent prompts."""
    scenes = [make_scenario(5, scenario_id=f"scene-{n:03d}", seed=n) for n in range(num_scenes)]
    source = folder / "scenes.tfrecord"
    write_scenarios(source, scenes)
    records = [
        make_record(
            s,
            [make_prompt((7, 17), "yielding/intersection")] if n % 2 == 0 else [make_prompt((7,)), make_prompt((37,))],
            source=str(source.resolve()),
            record=n,
        )
        for n, s in enumerate(scenes)
    ]
    labels = folder / "ds"
    (labels / "labels").mkdir(parents=True)
    write_shard(labels / "labels" / "0000-scenes.jsonl", records)
    write_manifest(labels, {"format_version": 1, "shards": [{"file": "labels/0000-scenes.jsonl"}]})
    return labels


TINY_TRAINING = {
    "name": "test-tiny",
    "stage": 2,
    "model": {"hidden_dim": 32, "num_heads": 4, "encoder_layers": 1, "denoiser_blocks": 1, "dropout": 0.0},
    "data": {"max_agents": 8, "max_polylines": 12, "points_per_polyline": 10},
    "batch_size": 4,
    "max_steps": 2,
    "val_every_steps": 1000,
    "checkpoint_every_steps": 1,
}
"""A stage-2 model small enough to train for two steps in seconds (CLI, simulation and demo tests)."""


def train_tiny(root: Path, num_scenes: int = 12) -> tuple[Path, Path]:
    """Train `TINY_TRAINING` with `langtraj train` on toy scenes in `root`: (last checkpoint, scenes file)."""
    import yaml

    from langtraj.cli.main import main

    labels = write_dataset(root, num_scenes)
    config = root / "tiny.yaml"
    config.write_text(yaml.safe_dump(TINY_TRAINING))
    assert main(["train", "--config", str(config), "--data", str(labels), "--out", str(root / "run")]) == 0
    return root / "run" / "checkpoints" / "last.ckpt", root / "scenes.tfrecord"
