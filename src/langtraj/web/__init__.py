"""What every web page LangTraj serves (the labeling tool, the studio) shares: security headers that let a page
load nothing but its own files, and the common scripts and style sheet under `/common` (static/: the DOM and
fetch helpers, the base CSS; docs/studio.md, 'The page's code')."""

from __future__ import annotations

from pathlib import Path

from fastapi import FastAPI
from fastapi.staticfiles import StaticFiles
from starlette.responses import Response

SECURITY_HEADERS = {
    "Content-Security-Policy": "default-src 'self'; img-src 'self' data:; media-src 'self'; object-src 'none'; "
    "base-uri 'none'; frame-ancestors 'none'",
    "X-Content-Type-Options": "nosniff",
    "Referrer-Policy": "no-referrer",
}

COMMON = Path(__file__).with_name("static")
"""The files every page loads from `/common`."""


def with_security_headers(response: Response) -> Response:
    """`response` with `SECURITY_HEADERS` and, unless it says otherwise, no caching (a new release's page, not a
    stale one)."""
    response.headers.update(SECURITY_HEADERS)
    response.headers.setdefault("Cache-Control", "no-cache")
    return response


def mount_pages(app: FastAPI, static: Path) -> None:
    """Serve an app's own page files under `/static` and the shared ones under `/common`."""
    app.mount("/common", StaticFiles(directory=COMMON), name="common")
    app.mount("/static", StaticFiles(directory=static), name="static")
