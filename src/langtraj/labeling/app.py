"""The labeling tool's web app (FastAPI): login, the three-step protocol page, task routing, review and
export over the database of `db.py`. Every write under /api/ passes `_guard` first, so an unauthenticated or
forged write gets 401 or 403 whatever its body. See docs/labeling.md ('Web API').
"""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import timedelta
from functools import cached_property
from pathlib import Path
from typing import Annotated, Any

from fastapi import Body, Depends, FastAPI, Request, Response
from fastapi.responses import FileResponse, JSONResponse
from pydantic import BaseModel, Field
from sqlalchemy import text
from starlette.concurrency import run_in_threadpool

from langtraj.errors import InputError
from langtraj.interdrive.dataset import WindowRecord, iter_records, load_window
from langtraj.interdrive.taxonomy import SINGLE_AGENT_LABELS, SUBTYPES, InteractionType
from langtraj.labeling import auth, review, tasks
from langtraj.labeling.auth import Identity
from langtraj.labeling.db import Database, default_url
from langtraj.labeling.errors import Conflict, Forbidden, NotFound
from langtraj.labeling.export import export_accepted
from langtraj.labeling.media import MediaConfig, agent_positions, window_video
from langtraj.labeling.models import Role
from langtraj.labeling.protocol import parse_labels
from langtraj.scenario.model import Scenario
from langtraj.web import mount_pages, with_security_headers

COOKIE = "langtraj_session"
CSRF_HEADER = "X-CSRF-Token"
STATIC = Path(__file__).with_name("static")
SAFE_METHODS = frozenset({"GET", "HEAD", "OPTIONS"})
OPEN_PATHS = frozenset({"/api/login"})


@dataclass(frozen=True)
class ServerConfig:
    """What `langtraj label serve` runs: the dataset, its database (default: SQLite in the dataset folder),
    how long a claimed slot stays locked, the video size, and whether cookies need HTTPS."""

    dataset: Path
    db_url: str | None = None
    lock_minutes: float = 30.0
    media: MediaConfig = field(default_factory=MediaConfig)
    secure_cookies: bool = False

    @property
    def url(self) -> str:
        return self.db_url or default_url(self.dataset)


class State:
    """The app's shared objects: the database, and the dataset's windows (read once, on first use)."""

    def __init__(self, config: ServerConfig, db: Database):
        self.config, self.db = config, db

    @cached_property
    def records(self) -> dict[str, WindowRecord]:
        return {r.scenario_id: r for _, recs in iter_records(self.config.dataset) for r in recs}

    def scene(self, scenario_id: str) -> Scenario:
        """The window of a task, read from the dataset's scenario file."""
        record = self.records.get(scenario_id)
        if record is None:
            raise NotFound(f"window {scenario_id!r} is not in the dataset any more")
        return load_window(record)

    @property
    def cache(self) -> Path:
        return Path(self.config.dataset) / ".labeling-cache"


# ---------------------------------------------------------------- request bodies


class LoginBody(BaseModel):
    name: str = Field(max_length=64)
    password: str = Field(max_length=1024)


class ChoiceBody(BaseModel):
    track_id: int
    other_id: int
    subtype: str = Field(max_length=64)
    text: str = Field(default="", max_length=4000)


class LabelsBody(BaseModel):
    pair: list[int] = Field(max_length=2)
    choices: list[ChoiceBody] = Field(max_length=2)


class StepTimes(BaseModel):
    """Milliseconds the annotator spent in each step of the protocol, as the page timed them."""

    model_config = {"extra": "forbid"}

    pair: int | None = Field(default=None, ge=0)
    type: int | None = Field(default=None, ge=0)
    subtype: int | None = Field(default=None, ge=0)


class SubmitBody(LabelsBody):
    submission_id: str = Field(min_length=8, max_length=64, pattern=r"^[A-Za-z0-9_-]+$")
    lead_time_ms: int = Field(ge=0, le=7 * 24 * 3600 * 1000)
    step_times_ms: StepTimes = Field(default_factory=lambda: StepTimes())


class AcceptBody(BaseModel):
    annotation_id: int | None = None
    labels: LabelsBody | None = None


# ---------------------------------------------------------------- the app


def create_app(config: ServerConfig, db: Database | None = None) -> FastAPI:
    """The app over `config`'s database (migrated to the newest schema; expired locks released)."""
    db = db or Database(config.url)
    tasks.release_expired(db)
    state = State(config, db)
    app = FastAPI(title="LangTraj InterDrive labeling", version="1", docs_url=None, redoc_url=None)
    app.state.labeling = state

    @app.middleware("http")
    async def _guard(request: Request, call_next):  # type: ignore[no-untyped-def]
        path = request.url.path
        if path.startswith("/api/") and path not in OPEN_PATHS:
            identity = await run_in_threadpool(_identify, db, request.cookies.get(COOKIE))
            if identity is None:
                return with_security_headers(JSONResponse({"detail": "log in first"}, status_code=401))
            if request.method not in SAFE_METHODS and not auth.csrf_matches(identity, request.headers.get(CSRF_HEADER)):
                refused = JSONResponse({"detail": f"missing or wrong {CSRF_HEADER} header"}, status_code=403)
                return with_security_headers(refused)
            request.state.identity = identity
        return with_security_headers(await call_next(request))

    for error, status in ((InputError, 422), (NotFound, 404), (Forbidden, 403), (Conflict, 409)):
        app.add_exception_handler(error, _handler(status))

    _routes(app, state)
    mount_pages(app, STATIC)
    return app


def _identify(db: Database, token: str | None) -> Identity | None:
    with db.session() as session:
        return auth.identify(session, token)


def _handler(status: int):  # type: ignore[no-untyped-def]
    async def handle(_request: Request, exc: Exception) -> JSONResponse:
        return JSONResponse({"detail": str(exc)}, status_code=status)

    return handle


def me(request: Request) -> Identity:
    return request.state.identity


def role(*roles: Role):  # type: ignore[no-untyped-def]
    """A dependency admitting only users with one of `roles` (403 for the others)."""

    def check(request: Request) -> Identity:
        identity = me(request)
        if not identity.may(*roles):
            raise Forbidden(f"needs role {' or '.join(r.value for r in roles)}")
        return identity

    return check


User = Annotated[Identity, Depends(me)]
Reviewer = Annotated[Identity, Depends(role(Role.REVIEWER, Role.ADMIN))]
Admin = Annotated[Identity, Depends(role(Role.ADMIN))]


def _routes(app: FastAPI, state: State) -> None:
    db, config = state.db, state.config

    @app.get("/", include_in_schema=False)
    def index() -> FileResponse:
        return FileResponse(STATIC / "index.html")

    @app.get("/healthz")
    def healthz() -> dict[str, str]:
        with db.session() as session:
            session.execute(text("select 1"))
        return {"status": "ok"}

    @app.post("/api/login")
    def login(body: LoginBody, response: Response) -> dict[str, Any]:
        with db.session() as session:
            user = auth.authenticate(session, body.name, body.password)
            if user is None:
                return JSONResponse({"detail": "wrong name or password"}, status_code=401)  # type: ignore[return-value]
            token, identity = auth.open_session(session, user)
        response.set_cookie(
            COOKIE, token, httponly=True, samesite="strict", secure=config.secure_cookies,
            max_age=int(auth.SESSION_LIFETIME.total_seconds()),
        )  # fmt: skip
        return _me(identity)

    @app.post("/api/logout")
    def logout(request: Request, response: Response) -> dict[str, str]:
        with db.session() as session:
            auth.close_session(session, request.cookies[COOKIE])
        response.delete_cookie(COOKIE)
        return {"status": "logged out"}

    @app.get("/api/me")
    def whoami(user: User) -> dict[str, Any]:
        return _me(user)

    @app.get("/api/taxonomy")
    def taxonomy(_: User) -> dict[str, Any]:
        return {
            "types": [{"key": k.value, "title": k.title} for k in InteractionType],
            "subtypes": [
                {"id": s.id, "type": s.type.value, "key": s.key, "name": s.name, "definition": s.definition}
                for s in SUBTYPES
            ],
            "agent_labels": [d.key for d in SINGLE_AGENT_LABELS],
        }

    @app.post("/api/tasks/next")
    def next_task(user: User) -> dict[str, Any]:
        claim = tasks.claim_next(db, user, timedelta(minutes=config.lock_minutes))
        if claim is None:
            return {"task": None}
        return {
            "slot_id": claim.slot_id,
            "locked_until": claim.locked_until,
            "task": tasks.task_view(db, claim.task_id),
        }

    @app.get("/api/tasks/{task_id}")
    def task(task_id: int, user: User) -> dict[str, Any]:
        tasks.may_view(db, user, task_id)
        return tasks.task_view(db, task_id)

    @app.get("/api/tasks/{task_id}/video")
    def video(task_id: int, user: User) -> FileResponse:
        tasks.may_view(db, user, task_id)
        view = tasks.task_view(db, task_id)
        path = window_video(state.scene(view["scenario_id"]), tuple(view["pair"]), state.cache, config.media)
        return FileResponse(path, media_type="video/mp4")

    @app.get("/api/tasks/{task_id}/positions")
    def positions(task_id: int, user: User) -> dict[str, Any]:
        tasks.may_view(db, user, task_id)
        return agent_positions(state.scene(tasks.task_view(db, task_id)["scenario_id"]), config.media)

    @app.post("/api/slots/{slot_id}/submit", status_code=201)
    def submit(slot_id: int, body: SubmitBody, user: User, response: Response) -> dict[str, Any]:
        labels = parse_labels(body.pair, [c.model_dump() for c in body.choices])
        annotation_id, created = tasks.submit(
            db,
            user,
            slot_id,
            body.submission_id,
            labels,
            body.lead_time_ms,
            body.step_times_ms.model_dump(exclude_none=True),
        )
        if not created:
            response.status_code = 200
        return {"annotation_id": annotation_id, "created": created}

    @app.post("/api/slots/{slot_id}/release")
    def release(slot_id: int, user: User) -> dict[str, str]:
        tasks.release(db, user, slot_id)
        return {"status": "released"}

    @app.put("/api/annotations/{annotation_id}")
    def edit(annotation_id: int, body: LabelsBody, user: User) -> dict[str, str]:
        labels = parse_labels(body.pair, [c.model_dump() for c in body.choices])
        tasks.edit(db, user, annotation_id, labels)
        return {"status": "updated"}

    @app.get("/api/progress")
    def progress(user: User) -> dict[str, Any]:
        """Overall progress; annotators see their own count only, reviewers and admins everyone's."""
        figures = tasks.progress(db)
        if not user.may(Role.REVIEWER, Role.ADMIN):
            figures["per_annotator"] = {user.name: figures["per_annotator"].get(user.name, 0)}
        return figures

    @app.get("/api/review/agreement")
    def agreement(_: Reviewer) -> dict[str, Any]:
        return review.agreement(db)

    @app.get("/api/review/queue")
    def review_queue(_: Reviewer) -> list[dict[str, Any]]:
        return review.queue(db)

    @app.post("/api/review/{task_id}/accept")
    def accept(task_id: int, body: AcceptBody, reviewer: Reviewer) -> dict[str, str]:
        labels = None
        if body.labels is not None:
            choices = [c.model_dump() for c in body.labels.choices]
            labels = parse_labels(body.labels.pair, choices)
        review.accept(db, reviewer, task_id, body.annotation_id, labels)
        return {"status": "accepted"}

    @app.post("/api/export")
    def export(_: Admin, into_dataset: Annotated[bool, Body(embed=True)] = False) -> dict[str, Any]:
        out = Path(config.dataset) / "labeling-export"
        result = export_accepted(db, out / "interdrive", out / "audit.json", config.dataset if into_dataset else None)
        state.__dict__.pop("records", None)  # an import rewrote the shards
        return {"folder": str(out), **result.__dict__}


def _me(identity: Identity) -> dict[str, Any]:
    return {"name": identity.name, "role": identity.role.value, "csrf": identity.csrf}
