"""Review: agreement between annotators (exact match of type and subtype per agent), acceptance by
consensus of a quorum, and the reviewer's queue of windows whose annotators disagree. See docs/labeling.md
('Review').
"""

from __future__ import annotations

from collections import Counter
from itertools import combinations
from typing import Any

from sqlalchemy import exists, select
from sqlalchemy.orm import Session, selectinload

from langtraj.labeling.auth import Identity
from langtraj.labeling.db import Database, utcnow
from langtraj.labeling.errors import Conflict, NotFound
from langtraj.labeling.models import Accepted, Annotation, SlotState, Task, User
from langtraj.labeling.protocol import AgentChoice, PairLabels, parse_labels, parse_subtype_id


def labels_of(annotation: Annotation) -> PairLabels:
    """An annotation's labels as the protocol's value (choices in pair order)."""
    by_agent = {(c.track_id, c.other_id): c for c in annotation.choices}
    a, b = annotation.agent_a, annotation.agent_b
    return PairLabels(
        (a, b),
        tuple(  # type: ignore[arg-type]
            AgentChoice(c.track_id, c.other_id, parse_subtype_id(c.subtype, "choice"), c.text)
            for c in (by_agent[(a, b)], by_agent[(b, a)])
        ),
    )


def _annotations(session: Session, task_id: int) -> list[Annotation]:
    return list(
        session.scalars(
            select(Annotation)
            .where(Annotation.task_id == task_id)
            .options(selectinload(Annotation.choices))
            .order_by(Annotation.id)
        )
    )


def settle(session: Session, task: Task) -> bool:
    """Accept `task` by consensus when `quorum` of its annotations match; True when it is accepted (now or
    before). Runs inside the transaction that changed the annotations, with the task row locked."""
    if session.get(Accepted, task.id) is not None:
        return True
    groups: dict[frozenset, list[Annotation]] = {}
    for a in _annotations(session, task.id):
        groups.setdefault(labels_of(a).key(), []).append(a)
    best = max(groups.values(), key=len, default=[])
    if len(best) < task.quorum:
        return False
    chosen = best[0]
    session.add(
        Accepted(
            task_id=task.id,
            method="consensus",
            reviewer_id=None,
            annotation_id=chosen.id,
            labels=labels_of(chosen).to_json(),
            accepted_at=utcnow(),
        )
    )
    return True


def _complete(task: Task) -> bool:
    return all(s.state == SlotState.DONE.value for s in task.slots)


def window_agreement(annotations: list[Annotation]) -> float | None:
    """The share of annotator pairs of a window whose labels match exactly; None below two annotations."""
    keys = [labels_of(a).key() for a in annotations]
    pairs = list(combinations(keys, 2))
    return sum(x == y for x, y in pairs) / len(pairs) if pairs else None


def agreement(db: Database) -> dict[str, Any]:
    """Agreement per window and per annotator (pairwise exact match with co-annotators, and match with the
    accepted labels)."""
    windows = []
    pair_hits: Counter[str] = Counter()
    pair_total: Counter[str] = Counter()
    acc_hits: Counter[str] = Counter()
    acc_total: Counter[str] = Counter()
    with db.session() as session:
        names = dict(session.execute(select(User.id, User.name)).all())
        for task in session.scalars(select(Task).order_by(Task.id)):
            annotations = _annotations(session, task.id)
            accepted = session.get(Accepted, task.id)
            keys = {a.id: labels_of(a).key() for a in annotations}
            for x, y in combinations(annotations, 2):
                same = keys[x.id] == keys[y.id]
                for a in (x, y):
                    pair_total[names[a.annotator_id]] += 1
                    pair_hits[names[a.annotator_id]] += same
            if accepted is not None:
                final = _accepted_labels(accepted).key()
                for a in annotations:
                    acc_total[names[a.annotator_id]] += 1
                    acc_hits[names[a.annotator_id]] += keys[a.id] == final
            windows.append(
                {
                    "task_id": task.id,
                    "scenario_id": task.scenario_id,
                    "annotations": len(annotations),
                    "agreement": window_agreement(annotations),
                    "status": _status(task, accepted),
                }
            )
    annotators = {
        name: {
            "pairwise": pair_hits[name] / pair_total[name] if pair_total[name] else None,
            "with_accepted": acc_hits[name] / acc_total[name] if acc_total[name] else None,
            "compared": pair_total[name],
        }
        for name in sorted(set(pair_total) | set(acc_total))
    }
    return {"windows": windows, "annotators": annotators}


def _status(task: Task, accepted: Accepted | None) -> str:
    if accepted is not None:
        return f"accepted ({accepted.method})"
    return "disagreement" if _complete(task) else "in progress"


def _accepted_labels(accepted: Accepted) -> PairLabels:
    pair = accepted.labels["pair"]
    return parse_labels(pair, accepted.labels["choices"])


def queue(db: Database) -> list[dict[str, Any]]:
    """Windows whose every slot is done but no quorum agrees: each with its annotations, for a reviewer."""
    out = []
    with db.session() as session:
        names = dict(session.execute(select(User.id, User.name)).all())
        for task in session.scalars(select(Task).where(~exists().where(Accepted.task_id == Task.id)).order_by(Task.id)):
            if not _complete(task):
                continue
            out.append(
                {
                    "task_id": task.id,
                    "scenario_id": task.scenario_id,
                    "annotations": [
                        {"annotation_id": a.id, "annotator": names[a.annotator_id], **labels_of(a).to_json()}
                        for a in _annotations(session, task.id)
                    ],
                }
            )
    return out


def accept(
    db: Database, reviewer: Identity, task_id: int, annotation_id: int | None, labels: PairLabels | None
) -> None:
    """A reviewer accepts one annotation of a task, or labels of their own, as final (replacing a consensus)."""
    with db.session() as session:
        task = session.get(Task, task_id)
        if task is None:
            raise NotFound(f"no task {task_id}")
        if (annotation_id is None) == (labels is None):
            raise Conflict("give either annotation_id or labels")
        if annotation_id is not None:
            annotation = session.get(Annotation, annotation_id)
            if annotation is None or annotation.task_id != task_id:
                raise NotFound(f"no annotation {annotation_id} of task {task_id}")
            labels = labels_of(annotation)
        assert labels is not None
        labels.check_window(task.agent_ids)
        row = session.get(Accepted, task_id) or Accepted(task_id=task_id)
        row.method, row.reviewer_id, row.annotation_id = "review", reviewer.id, annotation_id
        row.labels, row.accepted_at = labels.to_json(), utcnow()
        session.add(row)
