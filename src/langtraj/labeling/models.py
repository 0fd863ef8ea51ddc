"""The labeling tool's database tables (SQLAlchemy ORM); Alembic migrations in `migrations/` create them.

Times are naive UTC (`db.utcnow`), the same on SQLite and PostgreSQL.

One row per user, login session, task (a window to label), slot (one of a task's N annotator places, with
its lock), annotation (one annotator's submitted labels of a task), agent choice (one agent's type and
subtype towards the other, with the machine suggestion it replaced) and accepted label set. See
docs/labeling.md ('Database').
"""

from __future__ import annotations

from datetime import datetime
from enum import StrEnum
from typing import Any

from sqlalchemy import JSON, Boolean, DateTime, ForeignKey, Integer, String, Text, UniqueConstraint
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column, relationship


class Role(StrEnum):
    """What a user may do: annotators label, reviewers also resolve disagreements, admins also manage."""

    ANNOTATOR = "annotator"
    REVIEWER = "reviewer"
    ADMIN = "admin"


class SlotState(StrEnum):
    OPEN = "open"  # nobody holds it
    LOCKED = "locked"  # held by `annotator_id` until `locked_until`
    DONE = "done"  # its annotation is in


class Base(DeclarativeBase):
    type_annotation_map = {dict[str, Any]: JSON, list[Any]: JSON}  # noqa: RUF012


class User(Base):
    __tablename__ = "users"

    id: Mapped[int] = mapped_column(primary_key=True)
    name: Mapped[str] = mapped_column(String(64), unique=True)
    role: Mapped[str] = mapped_column(String(16))
    password_hash: Mapped[str] = mapped_column(String(255))
    created_at: Mapped[datetime] = mapped_column(DateTime())


class LoginSession(Base):
    """A browser session: the cookie holds a random token whose SHA-256 is stored; `csrf` must come back
    in the X-CSRF-Token header of every write."""

    __tablename__ = "sessions"

    token_hash: Mapped[str] = mapped_column(String(64), primary_key=True)
    user_id: Mapped[int] = mapped_column(ForeignKey("users.id", ondelete="CASCADE"), index=True)
    csrf: Mapped[str] = mapped_column(String(64))
    expires_at: Mapped[datetime] = mapped_column(DateTime())

    user: Mapped[User] = relationship(lazy="joined")


class Task(Base):
    """A window to label: `pair` is the candidate pair (WOMD objects of interest, pre-selected; else the
    detector's, only suggested), `suggestions` the detector's interactions [{track_id, other_id, subtype}],
    `overlap` the annotators it needs and `quorum` how many matching annotations accept it."""

    __tablename__ = "tasks"

    id: Mapped[int] = mapped_column(primary_key=True)
    scenario_id: Mapped[str] = mapped_column(String(255), unique=True)
    agents: Mapped[list[Any]] = mapped_column(JSON)  # [{"id": track id, "type": "vehicle"}]
    pair: Mapped[list[Any]] = mapped_column(JSON)  # the candidate pair's track ids, [] or [a, b]
    pair_source: Mapped[str] = mapped_column(String(24))  # "objects_of_interest", "detector" or "none"
    suggestions: Mapped[list[Any]] = mapped_column(JSON)
    overlap: Mapped[int] = mapped_column(Integer)
    quorum: Mapped[int] = mapped_column(Integer)
    created_at: Mapped[datetime] = mapped_column(DateTime())

    slots: Mapped[list[Slot]] = relationship(back_populates="task", order_by="Slot.number")

    @property
    def agent_ids(self) -> set[int]:
        """The track ids of the window."""
        return {int(a["id"]) for a in self.agents}


class Slot(Base):
    """One of a task's `overlap` annotator places. Claimed by compare-and-set on `version`, so no two
    annotators ever hold it at once; an annotator holds at most one slot of a task."""

    __tablename__ = "slots"
    __table_args__ = (
        UniqueConstraint("task_id", "number", name="uq_slot_number"),
        UniqueConstraint("task_id", "annotator_id", name="uq_slot_annotator"),
    )

    id: Mapped[int] = mapped_column(primary_key=True)
    task_id: Mapped[int] = mapped_column(ForeignKey("tasks.id", ondelete="CASCADE"), index=True)
    number: Mapped[int] = mapped_column(Integer)
    state: Mapped[str] = mapped_column(String(8), index=True)
    annotator_id: Mapped[int | None] = mapped_column(ForeignKey("users.id"))
    locked_at: Mapped[datetime | None] = mapped_column(DateTime())
    locked_until: Mapped[datetime | None] = mapped_column(DateTime())
    version: Mapped[int] = mapped_column(Integer, default=0)

    task: Mapped[Task] = relationship(back_populates="slots")


class Annotation(Base):
    """One annotator's labels of a task. `submission_id` is the client's idempotency key: a retried
    submit finds its first copy instead of writing a second."""

    __tablename__ = "annotations"

    id: Mapped[int] = mapped_column(primary_key=True)
    submission_id: Mapped[str] = mapped_column(String(64), unique=True)
    slot_id: Mapped[int] = mapped_column(ForeignKey("slots.id"), unique=True)
    task_id: Mapped[int] = mapped_column(ForeignKey("tasks.id", ondelete="CASCADE"), index=True)
    annotator_id: Mapped[int] = mapped_column(ForeignKey("users.id"), index=True)
    agent_a: Mapped[int] = mapped_column(Integer)
    agent_b: Mapped[int] = mapped_column(Integer)
    lead_time_ms: Mapped[int] = mapped_column(Integer)  # from claiming the task to submitting it
    step_times_ms: Mapped[dict[str, Any]] = mapped_column(JSON)  # per protocol step, as the client timed it
    submitted_at: Mapped[datetime] = mapped_column(DateTime())
    updated_at: Mapped[datetime | None] = mapped_column(DateTime())

    choices: Mapped[list[Choice]] = relationship(
        back_populates="annotation", order_by="Choice.id", cascade="all, delete-orphan"
    )


class Choice(Base):
    """What one agent does towards the other (asymmetric): a taxonomy subtype id ("yielding/intersection",
    "other/no_interaction", ...), free text for Other/undefined, and the machine suggestion shown."""

    __tablename__ = "choices"

    id: Mapped[int] = mapped_column(primary_key=True)
    annotation_id: Mapped[int] = mapped_column(ForeignKey("annotations.id", ondelete="CASCADE"), index=True)
    track_id: Mapped[int] = mapped_column(Integer)
    other_id: Mapped[int] = mapped_column(Integer)
    subtype: Mapped[str] = mapped_column(String(64))
    text: Mapped[str] = mapped_column(Text, default="")
    suggested: Mapped[str | None] = mapped_column(String(64))  # the detector's subtype, when it had one
    kept: Mapped[bool | None] = mapped_column(Boolean)  # suggestion kept (True) or changed (False); None: none

    annotation: Mapped[Annotation] = relationship(back_populates="choices")


class Accepted(Base):
    """A task's accepted labels: by consensus of `quorum` matching annotations, or by a reviewer."""

    __tablename__ = "accepted"

    task_id: Mapped[int] = mapped_column(ForeignKey("tasks.id", ondelete="CASCADE"), primary_key=True)
    method: Mapped[str] = mapped_column(String(16))  # "consensus" or "review"
    reviewer_id: Mapped[int | None] = mapped_column(ForeignKey("users.id"))
    annotation_id: Mapped[int | None] = mapped_column(ForeignKey("annotations.id"))  # the one taken, if any
    labels: Mapped[dict[str, Any]] = mapped_column(JSON)  # {"pair": [a, b], "choices": [{track_id, ...}]}
    accepted_at: Mapped[datetime] = mapped_column(DateTime())
