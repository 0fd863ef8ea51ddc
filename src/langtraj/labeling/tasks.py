"""Task routing: windows become tasks with `overlap` annotator slots; annotators claim a slot under a lock
with an expiry, submit it once, and see their progress. Claims are compare-and-set updates on the slot's
version, so no slot is ever held twice, on SQLite as on PostgreSQL. See docs/labeling.md ('Tasks').
"""

from __future__ import annotations

import random
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import timedelta
from pathlib import Path
from typing import Any

from sqlalchemy import and_, exists, func, or_, select, update
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from langtraj.errors import InputError
from langtraj.interdrive.dataset import WindowRecord, iter_records, load_window
from langtraj.interdrive.labels import LabelSource
from langtraj.labeling.auth import Identity
from langtraj.labeling.db import Database, utcnow
from langtraj.labeling.errors import Conflict, Forbidden, NotFound
from langtraj.labeling.models import Accepted, Annotation, Choice, Role, Slot, SlotState, Task, User
from langtraj.labeling.protocol import PairLabels, suggestion_for
from langtraj.labeling.review import settle
from langtraj.scenario.types import AgentType

DEFAULT_LOCK = timedelta(minutes=30)
CLAIM_WINDOW = 32
"""How many of the next free slots a claim considers (see `claim_next`)."""


# ---------------------------------------------------------------- adding tasks


def task_row(record: WindowRecord, overlap: int, quorum: int) -> Task:
    """A task for one dataset window: its agents, candidate pair and the detector's suggestions."""
    scene = load_window(record)
    ids = [int(i) for i in scene.agents.ids]
    agents = [{"id": t, "type": AgentType(int(k)).name.lower()} for t, k in zip(ids, scene.agents.types, strict=True)]
    suggestions = [
        {"track_id": i.track_id, "other_id": i.other_id, "subtype": i.subtype.id}
        for i in record.labels.interactions
        if i.source is LabelSource.DETECTOR and i.other_id >= 0
    ]
    ooi = [ids[int(n)] for n in scene.agents.objects_of_interest]
    if len(ooi) >= 2:
        pair, source = ooi[:2], "objects_of_interest"
    elif suggestions:
        pair, source = [suggestions[0]["track_id"], suggestions[0]["other_id"]], "detector"
    else:
        pair, source = [], "none"
    return Task(
        scenario_id=record.scenario_id,
        agents=agents,
        pair=pair,
        pair_source=source,
        suggestions=suggestions,
        overlap=overlap,
        quorum=quorum,
        created_at=utcnow(),
        slots=[Slot(number=n, state=SlotState.OPEN.value, version=0) for n in range(overlap)],
    )


def add_tasks(
    db: Database, dataset: Path, scenario_ids: Sequence[str] | None = None, overlap: int = 2, quorum: int | None = None
) -> tuple[int, int]:
    """Add windows of `dataset` (all, or `scenario_ids`) as tasks; returns (added, already there).

    An unknown scenario id raises InputError before anything is written."""
    quorum = overlap if quorum is None else quorum
    if overlap < 1:
        raise InputError(f"must be >= 1, got {overlap}", where="--overlap")
    if not 1 <= quorum <= overlap:
        raise InputError(f"must be between 1 and the overlap {overlap}, got {quorum}", where="--quorum")
    records = {r.scenario_id: r for _, recs in iter_records(dataset) for r in recs}
    wanted = list(records) if scenario_ids is None else list(dict.fromkeys(scenario_ids))
    unknown = [s for s in wanted if s not in records]
    if unknown:
        raise InputError(f"no window {unknown[0]!r} in the dataset", path=dataset, where="scenario id")
    with db.session() as session:
        present = set(session.scalars(select(Task.scenario_id)))
    new = [s for s in wanted if s not in present]
    rows = [task_row(records[s], overlap, quorum) for s in new]
    with db.session() as session:
        session.add_all(rows)
    return len(rows), len(wanted) - len(new)


# ---------------------------------------------------------------- claiming and submitting


@dataclass(frozen=True)
class Claim:
    slot_id: int
    task_id: int
    locked_until: str


def _held(session: Session, user: Identity) -> Slot | None:
    """A slot the user holds (its lock possibly expired but nobody took it)."""
    return session.scalar(
        select(Slot).where(Slot.annotator_id == user.id, Slot.state == SlotState.LOCKED.value).order_by(Slot.id)
    )


def _lock(session: Session, slot: Slot, user: Identity, lock: timedelta) -> bool:
    """Compare-and-set: take `slot` for `user` unless someone changed it since it was read."""
    now = utcnow()
    result = session.execute(
        update(Slot)
        .where(Slot.id == slot.id, Slot.version == slot.version)
        .values(
            state=SlotState.LOCKED.value,
            annotator_id=user.id,
            locked_at=now,
            locked_until=now + lock,
            version=Slot.version + 1,
        )
        .execution_options(synchronize_session=False)
    )
    return result.rowcount == 1


def claim_next(db: Database, user: Identity, lock: timedelta = DEFAULT_LOCK, attempts: int = 50) -> Claim | None:
    """Lock the next slot for `user`: the one it holds already, else the first free or expired slot of a task
    it has not labelled and that is not accepted; None when nothing is left.

    Should the first be taken meanwhile, the next CLAIM_WINDOW - 1 are tried in random order: concurrent
    claimers then spread over them instead of all racing for the same next slot (on PostgreSQL each lost
    race waits for the winner's commit)."""
    for _ in range(attempts):
        with db.session() as session:
            now = utcnow()
            held = _held(session, user)
            if held is not None:
                candidates = [held]
            else:
                other = Slot.__table__.alias("other")
                candidates = list(
                    session.scalars(
                        select(Slot)
                        .where(
                            or_(
                                Slot.state == SlotState.OPEN.value,
                                and_(Slot.state == SlotState.LOCKED.value, Slot.locked_until < now),
                            ),
                            ~exists().where(other.c.task_id == Slot.task_id, other.c.annotator_id == user.id),
                            ~exists().where(Accepted.task_id == Slot.task_id),
                        )
                        .order_by(Slot.task_id, Slot.number)
                        .limit(CLAIM_WINDOW)
                    )
                )
            if not candidates:
                return None
            rest = candidates[1:]
            random.shuffle(rest)
            candidates[1:] = rest
        for slot in candidates:
            try:
                with db.session() as session:
                    if _lock(session, slot, user, lock):
                        row = session.get(Slot, slot.id)
                        assert row is not None
                        return Claim(row.id, row.task_id, row.locked_until.isoformat() + "Z")
            except IntegrityError:
                continue  # a slot of this task became ours meanwhile; try the next
    raise Conflict("too much contention for slots; try again")


def release(db: Database, user: Identity, slot_id: int) -> None:
    """Give a held slot back to the queue."""
    with db.session() as session:
        slot = _own_slot(session, user, slot_id)
        if slot.state != SlotState.LOCKED.value:
            raise Conflict(f"slot {slot_id} is {slot.state}, not held")
        session.execute(_reopen(Slot.id == slot_id, Slot.version == slot.version))


def release_expired(db: Database) -> int:
    """Return every slot whose lock expired to the queue (at server start); returns how many."""
    with db.session() as session:
        result = session.execute(_reopen(Slot.state == SlotState.LOCKED.value, Slot.locked_until < utcnow()))
        return int(result.rowcount)


def _reopen(*where: Any) -> Any:
    """The update that puts the slots matching `where` back in the queue, unheld."""
    return (
        update(Slot)
        .where(*where)
        .values(
            state=SlotState.OPEN.value, annotator_id=None, locked_at=None, locked_until=None, version=Slot.version + 1
        )
        .execution_options(synchronize_session=False)
    )


def _own_slot(session: Session, user: Identity, slot_id: int) -> Slot:
    slot = session.get(Slot, slot_id)
    if slot is None:
        raise NotFound(f"no slot {slot_id}")
    if slot.annotator_id != user.id:
        raise Forbidden(f"slot {slot_id} is not yours")
    return slot


def _choices(labels: PairLabels, suggestions: Sequence[dict[str, Any]]) -> list[Choice]:
    rows = []
    for c in labels.choices:
        suggested = suggestion_for(suggestions, c.track_id, c.other_id)
        rows.append(
            Choice(
                track_id=c.track_id,
                other_id=c.other_id,
                subtype=c.subtype.id,
                text=c.text,
                suggested=suggested,
                kept=None if suggested is None else suggested == c.subtype.id,
            )
        )
    return rows


def submit(
    db: Database,
    user: Identity,
    slot_id: int,
    submission_id: str,
    labels: PairLabels,
    lead_time_ms: int,
    step_times_ms: dict[str, int],
) -> tuple[int, bool]:
    """Store the labels of the slot `user` holds and mark it done, in one transaction; returns (annotation id,
    created). A retry with the same `submission_id` returns the first copy (created False), even when it
    races the first copy."""
    earlier = _earlier_copy(db, user, submission_id)
    if earlier is not None:
        return earlier, False
    try:
        with db.session() as session:
            slot = _own_slot(session, user, slot_id)
            if slot.state != SlotState.LOCKED.value:
                raise Conflict(f"slot {slot_id} is {slot.state}: submitted already")
            done = session.execute(
                update(Slot)
                .where(Slot.id == slot_id, Slot.version == slot.version, Slot.annotator_id == user.id)
                .values(state=SlotState.DONE.value, locked_until=None, version=Slot.version + 1)
                .execution_options(synchronize_session=False)
            )
            if done.rowcount != 1:
                raise Conflict(f"slot {slot_id} changed hands; claim a new task")
            task = _locked_task(session, slot.task_id)
            labels.check_window(task.agent_ids)  # refused: the transaction rolls back, the slot stays held
            annotation = Annotation(
                submission_id=submission_id,
                slot_id=slot_id,
                task_id=task.id,
                annotator_id=user.id,
                agent_a=labels.pair[0],
                agent_b=labels.pair[1],
                lead_time_ms=lead_time_ms,
                step_times_ms=step_times_ms,
                submitted_at=utcnow(),
                choices=_choices(labels, task.suggestions),
            )
            session.add(annotation)
            session.flush()
            settle(session, task)
            return annotation.id, True
    except (Conflict, IntegrityError):
        earlier = _earlier_copy(db, user, submission_id)  # a retry that raced its first copy
        if earlier is None:
            raise
        return earlier, False


def _earlier_copy(db: Database, user: Identity, submission_id: str) -> int | None:
    """The id of the annotation `submission_id` already stored for `user`, if any."""
    with db.session() as session:
        first = session.scalar(select(Annotation).where(Annotation.submission_id == submission_id))
    if first is not None and first.annotator_id != user.id:
        raise Conflict("submission id used by another annotator")
    return None if first is None else first.id


def _locked_task(session: Session, task_id: int) -> Task:
    """The task row, locked until the transaction ends (PostgreSQL; SQLite has one writer at a time), so
    that concurrent submits of one window settle its consensus one after the other."""
    task = session.get(Task, task_id, with_for_update=True)
    if task is None:
        raise NotFound(f"no task {task_id}")
    return task


def edit(db: Database, user: Identity, annotation_id: int, labels: PairLabels) -> None:
    """Replace the labels of the user's own annotation, until its task is accepted."""
    with db.session() as session:
        annotation = session.get(Annotation, annotation_id)
        if annotation is None:
            raise NotFound(f"no annotation {annotation_id}")
        if annotation.annotator_id != user.id:
            raise Forbidden(f"annotation {annotation_id} is another annotator's")
        if session.get(Accepted, annotation.task_id) is not None:
            raise Conflict(f"task {annotation.task_id} is accepted; its labels are final")
        task = _locked_task(session, annotation.task_id)
        labels.check_window(task.agent_ids)
        annotation.agent_a, annotation.agent_b = labels.pair
        annotation.choices = _choices(labels, task.suggestions)
        annotation.updated_at = utcnow()
        session.flush()
        settle(session, task)


# ---------------------------------------------------------------- reading


def task_view(db: Database, task_id: int) -> dict[str, Any]:
    """What the labeling page shows of a task."""
    with db.session() as session:
        task = session.get(Task, task_id)
        if task is None:
            raise NotFound(f"no task {task_id}")
        return {
            "task_id": task.id,
            "scenario_id": task.scenario_id,
            "agents": task.agents,
            "pair": task.pair,
            "pair_source": task.pair_source,
            "suggestions": task.suggestions,
            "overlap": task.overlap,
        }


def may_view(db: Database, user: Identity, task_id: int) -> None:
    """Raise Forbidden unless `user` reviews (reviewer, admin) or holds or held a slot of the task: an
    annotator sees only the windows routed to them."""
    if user.may(Role.REVIEWER, Role.ADMIN):
        return
    with db.session() as session:
        if session.get(Task, task_id) is None:
            raise NotFound(f"no task {task_id}")
        if session.scalar(select(Slot.id).where(Slot.task_id == task_id, Slot.annotator_id == user.id)) is None:
            raise Forbidden(f"task {task_id} is not routed to you")


def progress(db: Database) -> dict[str, Any]:
    """Slots done per annotator and overall, and tasks accepted."""
    with db.session() as session:
        per_user = session.execute(
            select(User.name, func.count(Annotation.id))
            .join(Annotation, Annotation.annotator_id == User.id)
            .group_by(User.name)
            .order_by(User.name)
        ).all()
        states = dict(session.execute(select(Slot.state, func.count()).group_by(Slot.state)).all())
        tasks = session.scalar(select(func.count()).select_from(Task)) or 0
        accepted = session.scalar(select(func.count()).select_from(Accepted)) or 0
    slots = sum(states.values())
    return {
        "tasks": tasks,
        "tasks_accepted": accepted,
        "slots": slots,
        "slots_done": states.get(SlotState.DONE.value, 0),
        "slots_locked": states.get(SlotState.LOCKED.value, 0),
        "per_annotator": {name: count for name, count in per_user},
    }
