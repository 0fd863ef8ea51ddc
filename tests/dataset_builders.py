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
            [make_prompt((7, 17), "yield/yield_to")] if n % 2 == 0 else [make_prompt((7,)), make_prompt((37,))],
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
