"""A ready-to-label demo: a few SUMO windows, their InterDrive dataset, tasks, and demo accounts with fresh
random passwords (`langtraj label demo`). See docs/labeling.md ('Try it').
"""

from __future__ import annotations

import secrets
from dataclasses import dataclass
from pathlib import Path

from langtraj.interdrive.dataset import BuildConfig, build_dataset
from langtraj.labeling.auth import create_user
from langtraj.labeling.db import Database, default_url
from langtraj.labeling.models import Role, User
from langtraj.labeling.tasks import add_tasks
from langtraj.scenario.io import expand_scenario_paths

DEMO_USERS = (
    ("admin", Role.ADMIN),
    ("reviewer", Role.REVIEWER),
    ("annotator1", Role.ANNOTATOR),
    ("annotator2", Role.ANNOTATOR),
)


@dataclass(frozen=True)
class DemoSetup:
    dataset: Path
    passwords: dict[str, str]  # user name -> password; empty when the accounts existed already
    tasks_added: int


def prepare_demo(
    folder: Path, db_url: str | None = None, windows: int = 4, seed: int = 0, overlap: int = 2
) -> DemoSetup:
    """Synthesize `windows` signalized-intersection windows into `folder`, label them, add them as tasks with
    `overlap` annotators each, and create the demo accounts (once: a rerun keeps them and their passwords)."""
    from langtraj.synth.factory import FactoryConfig, run_factory
    from langtraj.synth.network import parse_kinds

    folder = Path(folder)
    scenes = folder / "scenes"
    if not (scenes / "manifest.json").is_file():
        run_factory(
            FactoryConfig(kinds=parse_kinds("signalized"), windows=windows, seed=seed, out=scenes), progress=False
        )
    dataset = folder / "dataset"
    build_dataset(expand_scenario_paths([scenes / "shards"]), dataset, BuildConfig(seed=seed))
    db = Database(db_url or default_url(dataset))
    try:
        passwords = {}
        with db.session() as session:
            if session.query(User).count() == 0:
                for name, role in DEMO_USERS:
                    passwords[name] = secrets.token_urlsafe(12)
                    create_user(session, name, passwords[name], role)
        added, _ = add_tasks(db, dataset, overlap=overlap)
    finally:
        db.dispose()
    return DemoSetup(dataset, passwords, added)
