"""LangTraj Studio's web app (FastAPI): the scene list and views, prompt checks, simulation jobs run in the
background, their judged results, rollouts and video, and saving a job as a test-suite case. Every error is
JSON `{"error": "one line"}`. See docs/studio.md ('The HTTP API')."""

from __future__ import annotations

from contextlib import asynccontextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fastapi import FastAPI, Request, Response
from fastapi.exceptions import RequestValidationError
from fastapi.responses import FileResponse, JSONResponse
from fastapi.staticfiles import StaticFiles
from starlette.exceptions import HTTPException as StarletteHTTPException

from langtraj.errors import InputError
from langtraj.studio.catalog import Catalog
from langtraj.studio.views import scene_view

STATIC = Path(__file__).with_name("static")
MAX_BODY_BYTES = 256 * 1024
"""Request bodies above this are refused (413): prompts are short, and nothing else is uploaded."""
SECURITY_HEADERS = {
    "Content-Security-Policy": "default-src 'self'; img-src 'self' data:; media-src 'self'; object-src 'none'; "
    "base-uri 'none'; frame-ancestors 'none'",
    "X-Content-Type-Options": "nosniff",
    "Referrer-Policy": "no-referrer",
}


@dataclass(frozen=True)
class StudioConfig:
    """What `langtraj studio` serves: the scene files and folders, the checkpoint (None: the shipped one) and
    the data folder (jobs, suites)."""

    paths: tuple[Path, ...]
    checkpoint: Path | None = None
    data: Path = Path("studio-data")


class NotFound(Exception):
    """A key or job id the studio does not know (404)."""


def create_app(config: StudioConfig, catalog: Catalog | None = None) -> FastAPI:
    """The studio over `config` (`catalog`: an already built scene list)."""
    catalog = catalog or Catalog.build(config.paths)

    @asynccontextmanager
    async def lifespan(_app: FastAPI):  # type: ignore[no-untyped-def]
        yield

    app = FastAPI(title="LangTraj Studio", version="1", docs_url=None, redoc_url=None, lifespan=lifespan)
    app.state.catalog = catalog

    @app.middleware("http")
    async def _guard(request: Request, call_next):  # type: ignore[no-untyped-def]
        length = request.headers.get("content-length")
        if length is not None and (not length.isdigit() or int(length) > MAX_BODY_BYTES):
            return _headers(_error(f"request body over {MAX_BODY_BYTES} bytes", 413))
        if request.method == "POST" and length is None and "chunked" in request.headers.get("transfer-encoding", ""):
            return _headers(_error("send a Content-Length with the request body", 411))
        return _headers(await call_next(request))

    app.add_exception_handler(InputError, _handler(400))
    app.add_exception_handler(NotFound, _handler(404))
    app.add_exception_handler(RequestValidationError, _validation)
    app.add_exception_handler(StarletteHTTPException, _http)
    _scene_routes(app, catalog)
    app.mount("/static", StaticFiles(directory=STATIC), name="static")
    return app


def _headers(response: Response) -> Response:
    response.headers.update(SECURITY_HEADERS)
    response.headers.setdefault("Cache-Control", "no-cache")
    return response


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
