"""What every web page LangTraj serves (the labeling tool, the studio) sends with each response: security headers
that let a page load nothing but its own files (docs/labeling.md, docs/studio.md)."""

from __future__ import annotations

from starlette.responses import Response

SECURITY_HEADERS = {
    "Content-Security-Policy": "default-src 'self'; img-src 'self' data:; media-src 'self'; object-src 'none'; "
    "base-uri 'none'; frame-ancestors 'none'",
    "X-Content-Type-Options": "nosniff",
    "Referrer-Policy": "no-referrer",
}


def with_security_headers(response: Response) -> Response:
    """`response` with `SECURITY_HEADERS` and, unless it says otherwise, no caching (a new release's page, not a
    stale one)."""
    response.headers.update(SECURITY_HEADERS)
    response.headers.setdefault("Cache-Control", "no-cache")
    return response
