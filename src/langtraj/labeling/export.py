"""Export: accepted labels as InterDrive JSON (the layout of `langtraj interdrive export`), optionally merged
into the dataset as human labels, and an audit file of who labelled what, whether they kept the machine
suggestion, and how long it took. See docs/labeling.md ('Export').
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import selectinload

from langtraj.errors import InputError
from langtraj.fileio import atomic_open
from langtraj.interdrive.exchange import agent_entry, import_json, write_scene
from langtraj.labeling.db import Database
from langtraj.labeling.models import Accepted, Annotation, Task, User
from langtraj.labeling.protocol import parse_subtype_id

AUDIT_VERSION = 1


@dataclass(frozen=True)
class ExportResult:
    written: int  # InterDrive JSON files
    pending: int  # tasks not accepted yet (left out)
    imported: int  # windows updated in the dataset (0 without `into`)


def export_accepted(db: Database, out: Path, audit: Path | None = None, into: Path | None = None) -> ExportResult:
    """Write `{scenario_id}.json` per accepted task into `out`, the audit file to `audit` (default
    `out/../labeling-audit.json`), and, with `into`, import the files into that dataset as human labels."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InputError("exists and is not a folder", path=out)
    written, records = 0, []
    with db.session() as session:
        names = dict(session.execute(select(User.id, User.name)).all())
        tasks = list(session.scalars(select(Task).order_by(Task.id)))
        for task in tasks:
            accepted = session.get(Accepted, task.id)
            annotations = list(
                session.scalars(
                    select(Annotation)
                    .where(Annotation.task_id == task.id)
                    .options(selectinload(Annotation.choices))
                    .order_by(Annotation.id)
                )
            )
            if accepted is not None:
                choices = accepted.labels["choices"]
                entries = [
                    agent_entry(c["track_id"], parse_subtype_id(c["subtype"], "accepted"), c.get("text", ""))
                    for c in choices
                ]
                write_scene(out, task.scenario_id, entries[0], entries[1])
                written += 1
            records.append(_audit_record(task, accepted, annotations, names))
    audit = Path(audit) if audit is not None else out.parent / "labeling-audit.json"
    with atomic_open(audit, "w") as fh:
        json.dump({"audit_version": AUDIT_VERSION, "windows": records}, fh, indent=1)
    imported = import_json(out, into) if into is not None and written else 0
    return ExportResult(written, len(tasks) - written, imported)


def _audit_record(task: Task, accepted: Accepted | None, annotations: list[Annotation], names: dict) -> dict[str, Any]:
    return {
        "scenario_id": task.scenario_id,
        "candidate_pair": task.pair,
        "candidate_pair_source": task.pair_source,
        "accepted": None
        if accepted is None
        else {
            "method": accepted.method,
            "reviewer": names.get(accepted.reviewer_id),
            "annotation_id": accepted.annotation_id,
            "at": accepted.accepted_at.isoformat() + "Z",
            **accepted.labels,
        },
        "annotations": [
            {
                "annotation_id": a.id,
                "annotator_id": a.annotator_id,
                "annotator": names[a.annotator_id],
                "submitted_at": a.submitted_at.isoformat() + "Z",
                "edited_at": None if a.updated_at is None else a.updated_at.isoformat() + "Z",
                "lead_time_ms": a.lead_time_ms,
                "step_times_ms": a.step_times_ms,
                "pair": [a.agent_a, a.agent_b],
                "choices": [
                    {
                        "track_id": c.track_id,
                        "other_id": c.other_id,
                        "subtype": c.subtype,
                        "text": c.text,
                        "suggested": c.suggested,
                        "suggestion": None if c.kept is None else ("kept" if c.kept else "changed"),
                    }
                    for c in a.choices
                ],
            }
            for a in annotations
        ],
    }
