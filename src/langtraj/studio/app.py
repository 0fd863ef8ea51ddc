"""LangTraj Studio's web app (FastAPI): the scene list and views, prompt checks, what a scene can stage against an
ego, simulation jobs run in the background, their judged results, rollouts and video, and saving a job as a
test-suite case. Every error is JSON `{"error": "one line"}`. See docs/studio.md ('The HTTP API')."""

from __future__ import annotations

import threading
from contextlib import asynccontextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any

from fastapi import FastAPI, Query, Request, Response
from fastapi.exceptions import RequestValidationError
from fastapi.responses import FileResponse, JSONResponse
from pydantic import BaseModel, Field
from starlette.exceptions import HTTPException as StarletteHTTPException

from langtraj.cases import NAME, read_case
from langtraj.errors import InputError
from langtraj.fileio import read_json
from langtraj.roads import MapIndex
from langtraj.scenario.model import Scenario
from langtraj.sim.prompt_checks import PromptChecks
from langtraj.studio.cases import DuplicateCase, case_of, save_case
from langtraj.studio.catalog import Catalog
from langtraj.studio.jobs import Job, JobBoard, JobSpec, JobStore, Runner
from langtraj.studio.simulation import RESULT_FILE, ROLLOUTS_FILE, JobRunner, job_checks
from langtraj.studio.stagings import StagingLists, behaviours_of, staging_json
from langtraj.studio.views import scene_view
from langtraj.web import mount_pages, with_security_headers

STATIC = Path(__file__).with_name("static")
MAX_BODY_BYTES = 256 * 1024
"""Request bodies above this are refused (413): prompts are short, and nothing else is uploaded."""


@dataclass(frozen=True)
class StudioConfig:
    """What `langtraj studio` serves: the scene files and folders, the checkpoint (None: the shipped one) and
    the data folder (jobs, suites)."""

    paths: tuple[Path, ...]
    checkpoint: Path | None = None
    data: Path = Path("studio-data")


VIDEO_FILE = "video.mp4"
VIDEO_PX = 640
MAX_PROMPTS = 16
MAX_ROLLOUTS = 16
DEFAULT_PLANNER = "idm"
_NAME = NAME.pattern  # suite and case names, as `langtraj test` reads them


class NotFound(Exception):
    """A key or job id the studio does not know, or a file a job does not have yet (404)."""


class Conflict(Exception):
    """A request that clashes with what is there (409)."""


# ---------------------------------------------------------------- request bodies


class PromptsBody(BaseModel):
    model_config = {"extra": "forbid"}

    prompts: list[str] = Field(default_factory=list, max_length=MAX_PROMPTS)
    adversary: int | None = None
    target: int | None = None


class PlannedBody(PromptsBody):
    planner: str | None = Field(default=DEFAULT_PLANNER, max_length=64)
    """A registered planner driving the ego (the case's episodes, as `langtraj test` runs them); null: every agent
    simulated, the ego too."""


class JobBody(PlannedBody):
    scene: str = Field(max_length=64)
    rollouts: int = Field(default=4, ge=1, le=MAX_ROLLOUTS)
    seed: int = Field(default=0, ge=0, le=2**31 - 1)
    compare: bool = True


class CaseBody(BaseModel):
    model_config = {"extra": "forbid"}

    suite: str = Field(max_length=100, pattern=f"^{_NAME}$")
    name: str = Field(max_length=100, pattern=f"^{_NAME}$")
    criteria: dict[str, Any] | None = None


# ---------------------------------------------------------------- the app


def create_app(
    config: StudioConfig, catalog: Catalog | None = None, runner: Runner | None = None, *, start_worker: bool = True
) -> FastAPI:
    """The studio over `config` (`catalog`: an already built scene list; `runner`: what runs a job, by default the
    closed-loop simulation). Jobs on disk are reloaded; the worker starts unless `start_worker` is False."""
    catalog = catalog or Catalog.build(config.paths)
    board = JobBoard(JobStore(Path(config.data) / "jobs"), runner or JobRunner(catalog, config.checkpoint))
    if start_worker:
        board.start()

    @asynccontextmanager
    async def lifespan(_app: FastAPI):  # type: ignore[no-untyped-def]
        yield
        board.close()

    app = FastAPI(title="LangTraj Studio", version="1", docs_url=None, redoc_url=None, lifespan=lifespan)
    app.state.catalog = catalog
    app.state.board = board

    @app.middleware("http")
    async def _guard(request: Request, call_next):  # type: ignore[no-untyped-def]
        length = request.headers.get("content-length")
        if length is not None and (not length.isdigit() or int(length) > MAX_BODY_BYTES):
            return with_security_headers(_error(f"request body over {MAX_BODY_BYTES} bytes", 413))
        if request.method == "POST" and length is None and "chunked" in request.headers.get("transfer-encoding", ""):
            return with_security_headers(_error("send a Content-Length with the request body", 411))
        return with_security_headers(await call_next(request))

    app.add_exception_handler(InputError, _handler(400))
    app.add_exception_handler(NotFound, _handler(404))
    app.add_exception_handler(Conflict, _handler(409))
    app.add_exception_handler(RequestValidationError, _validation)
    app.add_exception_handler(StarletteHTTPException, _http)
    _scene_routes(app, catalog)
    _job_routes(app, catalog, board, Path(config.data) / "suites", config.checkpoint)
    mount_pages(app, STATIC)
    return app


def _error(message: str, status: int) -> JSONResponse:
    return JSONResponse({"error": message}, status_code=status)


def _handler(status: int):  # type: ignore[no-untyped-def]
    async def handle(_request: Request, exc: Exception) -> JSONResponse:
        return _error(str(exc), status)

    return handle


async def _validation(_request: Request, exc: Exception) -> JSONResponse:
    """A malformed body as one line: the first problem, where it is."""
    errors = exc.errors() if isinstance(exc, RequestValidationError) else []
    if not errors:
        return _error("malformed request", 400)
    first = errors[0]
    where = ".".join(str(p) for p in first.get("loc", ()) if p != "body") or "body"
    more = f" (and {len(errors) - 1} more)" if len(errors) > 1 else ""
    return _error(f"{where}: {first.get('msg', 'invalid')}{more}", 400)


async def _http(_request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, StarletteHTTPException)
    return _error(str(exc.detail), exc.status_code)


def _scene_routes(app: FastAPI, catalog: Catalog) -> None:
    @app.get("/", include_in_schema=False)
    def index() -> Response:
        page = STATIC / "index.html"
        if not page.is_file():
            return _error("the studio's page is not installed (studio/static/index.html)", 404)
        return FileResponse(page)

    @app.get("/api/scenes")
    def scenes(
        q: str | None = None, kind: str | None = None, min_agents: int | None = None, max_agents: int | None = None
    ) -> dict[str, Any]:
        found = catalog.search(q, kind, min_agents, max_agents)
        return {"scenes": [e.to_json() for e in found], "errors": [e.to_json() for e in catalog.errors]}

    @app.get("/api/scenes/{key}")
    def scene(key: str) -> dict[str, Any]:
        loaded = catalog.load(key)
        if loaded is None:
            raise NotFound(f"no scene {key!r}")
        return scene_view(key, loaded.scenario)

    @app.post("/api/scenes/{key}/prompts")
    def prompts(key: str, body: PlannedBody) -> dict[str, Any]:
        loaded = catalog.load(key)
        if loaded is None:
            raise NotFound(f"no scene {key!r}")
        return _checks(loaded.scenario, body, loaded.map_index).to_json()

    stagings_of = StagingLists()

    @app.get("/api/scenes/{key}/stagings")
    def stagings(
        key: str, ego: int | None = None, behaviour: Annotated[list[str] | None, Query(max_length=16)] = None
    ) -> dict[str, Any]:
        """What the scene can stage against `ego` (default: the planner's), most natural first (`langtraj
        suggest`); a plain def, so the search runs in the thread pool, off the event loop, as the prompt checks do."""
        loaded = catalog.load(key)
        if loaded is None:
            raise NotFound(f"no scene {key!r}")
        ego, found = stagings_of.find(loaded, ego, behaviours_of(behaviour or ()))
        return {"ego": ego, "stagings": [staging_json(s) for s in found]}


def _job_routes(app: FastAPI, catalog: Catalog, board: JobBoard, suites: Path, checkpoint: Path | None) -> None:
    video_lock = threading.Lock()

    def job_of(job_id: str) -> Job:
        job = board.get(job_id)
        if job is None:
            raise NotFound(f"no job {job_id!r}")
        return job

    def done_file(job_id: str, name: str) -> Path:
        job = job_of(job_id)
        path = board.folder(job.id) / name
        if job.status != "done" or not path.is_file():
            raise NotFound(f"job {job.id} is {job.status}: no {name} yet")
        return path

    @app.post("/api/jobs", status_code=201)
    def submit(body: JobBody) -> dict[str, Any]:
        loaded = catalog.load(body.scene)
        if loaded is None:
            raise NotFound(f"no scene {body.scene!r}")
        checks = _checks(loaded.scenario, body, loaded.map_index)
        if not checks.ok:
            raise InputError(checks.first_error() or "the prompts cannot be run")
        if not body.prompts and body.adversary is None and body.compare:
            raise InputError("no prompts and no collision pair: the run and its comparison would be the same run")
        entry = catalog.entry(body.scene)
        case = {"scenario": entry.file, "index": entry.index, "window": entry.window, "prompts": body.prompts}
        seeds = list(range(body.seed, body.seed + body.rollouts)) if body.planner else [body.seed]
        case |= {"adversary": body.adversary, "target": body.target, "seeds": seeds}
        case |= {"criteria": {"terminate_on_collision": False}}  # the watched episodes run their 8 s
        case = read_case(case | {"checkpoint": checkpoint})
        spec = JobSpec(body.scene, loaded.scenario.scenario_id, case, body.rollouts, body.compare, planner=body.planner)
        return {"job": board.submit(spec).to_json()}

    @app.post("/api/jobs/{job_id}/resubmit", status_code=201)
    def resubmit(job_id: str) -> dict[str, Any]:
        """A new job of an interrupted or failed job's spec, checked again (the scene or the studio may differ)."""
        old = job_of(job_id)
        if old.status not in ("interrupted", "failed"):
            raise Conflict(f"job {old.id} is {old.status}: only an interrupted or failed job is submitted again")
        loaded = catalog.load(old.spec.scene)
        if loaded is None:
            raise NotFound(f"no scene {old.spec.scene!r} in this studio's catalog")
        case = old.spec.case
        body = PlannedBody(
            prompts=list(case.prompts), adversary=case.adversary, target=case.target, planner=old.spec.planner
        )
        checks = _checks(loaded.scenario, body, loaded.map_index)
        if not checks.ok:
            raise InputError(checks.first_error() or "the prompts cannot be run")
        return {"job": board.submit(old.spec).to_json()}

    @app.get("/api/jobs")
    def jobs() -> dict[str, Any]:
        return {"jobs": [j.to_json() for j in board.jobs()]}

    @app.get("/api/jobs/{job_id}")
    def job(job_id: str) -> dict[str, Any]:
        found = job_of(job_id)
        out = found.to_json()
        result = board.folder(found.id) / RESULT_FILE
        if found.status == "done" and result.is_file():
            out["result"] = read_json(result, "no result file")
        return out

    @app.get("/api/jobs/{job_id}/rollouts.npz")
    def rollouts(job_id: str) -> FileResponse:
        path = done_file(job_id, ROLLOUTS_FILE)
        return FileResponse(path, media_type="application/octet-stream", filename=f"{job_id}-rollouts.npz")

    @app.get("/api/jobs/{job_id}/video.mp4")
    def video(job_id: str) -> FileResponse:
        path = done_file(job_id, ROLLOUTS_FILE).with_name(VIDEO_FILE)
        with video_lock:  # one render at a time; a second request for the same video waits for the first
            if not path.is_file():
                _render(catalog, job_of(job_id), path)
        return FileResponse(path, media_type="video/mp4")

    @app.post("/api/jobs/{job_id}/case")
    def case(job_id: str, body: CaseBody) -> dict[str, Any]:
        found = job_of(job_id)
        try:
            path = save_case(suites, body.suite, case_of(found, body.name, body.criteria))
        except DuplicateCase as exc:
            raise Conflict(str(exc)) from None
        command = f"langtraj test {path} --planner {found.spec.planner} --out runs/{body.suite}"
        return {"suite": str(path), "case": body.name, "planner": found.spec.planner, "command": command}


def _checks(scenario: Scenario, body: PlannedBody, index: MapIndex) -> PromptChecks:
    """`job_checks` of a request's prompts, pair and planner."""
    return job_checks(scenario, body.prompts, body.adversary, body.target, body.planner, index)


def _render(catalog: Catalog, job: Job, path: Path) -> None:
    """Rollout 0 of the job's prompted run as a video: the prompted agents and the collision pair highlighted,
    each prompt's target marked, from the current step on (written atomically by `save_video`)."""
    from langtraj.metrics.instruction_following import rollout_scenario
    from langtraj.rollouts.container import Rollouts
    from langtraj.sim.prompts import prompt_mentions
    from langtraj.viz import RenderConfig, marks_from_prompt, save_video

    loaded = catalog.load(job.spec.scene)
    if loaded is None:
        raise NotFound(f"no scene {job.spec.scene!r} in this studio's catalog")
    scenario = loaded.scenario
    folder = path.parent
    played = rollout_scenario(scenario, Rollouts.load(folder / ROLLOUTS_FILE), 0)
    result = read_json(folder / RESULT_FILE, "no result file")
    case = job.spec.case
    named = prompt_mentions(scenario, case.prompts)
    named += [t for t in (case.adversary, case.target) if t is not None and t not in named]
    caption = "; ".join(case.prompts)[:120] or "no prompt"
    marks = marks_from_prompt({"targets": result["runs"]["prompted"]["targets"]})
    render = RenderConfig(size_px=VIDEO_PX, highlight_ids=tuple(named), show_ids=True, caption=caption, marks=marks)
    save_video(played, path, render, start=scenario.current_index, progress=False)
