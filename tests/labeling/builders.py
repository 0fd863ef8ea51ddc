"""A small InterDrive dataset and a labeling database over it, for the labeling tool's tests."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from scenario_builders import make_scenario

from langtraj.interdrive.dataset import BuildConfig, build_dataset, iter_records, write_shard
from langtraj.interdrive.labels import InteractionLabel, LabelSource
from langtraj.interdrive.taxonomy import SUBTYPES_BY_ID
from langtraj.labeling.auth import Identity, create_user
from langtraj.labeling.db import Database
from langtraj.labeling.models import Role
from langtraj.scenario.io import write_scenarios

PASSWORD = "correct horse battery"
SUGGESTED = "yielding/intersection"
"""The detector's suggestion the dataset carries for @17 towards @7 in every window."""


def make_label_dataset(folder: Path, num_scenes: int = 3) -> Path:
    """A dataset of `num_scenes` toy windows (agents 7, 17, 27, 37; objects of interest 7 and 17) built by the
    real pipeline, plus one detector suggestion per window."""
    scenes = [make_scenario(4, 40, scenario_id=f"win-{n}", seed=n) for n in range(num_scenes)]
    source = folder / "scenes.tfrecord"
    write_scenarios(source, scenes)
    dataset = folder / "ds"
    build_dataset([source], dataset, BuildConfig(prompts_per_agent=1))
    for shard, records in iter_records(dataset):
        suggestion = InteractionLabel(17, 7, SUBTYPES_BY_ID[SUGGESTED], LabelSource.DETECTOR, 10, 40)
        write_shard(
            shard,
            [replace(r, labels=replace(r.labels, interactions=(*r.labels.interactions, suggestion))) for r in records],
        )
    return dataset


def add_user(db: Database, name: str, role: Role = Role.ANNOTATOR) -> Identity:
    with db.session() as session:
        user = create_user(session, name, PASSWORD, role)
        session.flush()
        return Identity(user.id, user.name, role, csrf="")


def labels_body(subtype_a: str = "passing/intersection_with_yielding", subtype_b: str = SUGGESTED, text: str = ""):
    """A submission's labels for the pair (7, 17): 7 towards 17, then 17 towards 7; `text` goes to the choice
    that is Other / Undefined behavior."""
    undefined = "other/undefined"
    return {
        "pair": [7, 17],
        "choices": [
            {"track_id": 7, "other_id": 17, "subtype": subtype_a, "text": text if subtype_a == undefined else ""},
            {"track_id": 17, "other_id": 7, "subtype": subtype_b, "text": text if subtype_b == undefined else ""},
        ],
    }
