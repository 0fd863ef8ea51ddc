"""What every web page LangTraj serves (the labeling tool, the studio) sends with each response: security headers
that let a page load nothing but its own files (docs/labeling.md, docs/studio.md)."""

from __future__ import annotations

SECURITY_HEADERS = {
    "Content-Security-Policy": "default-src 'self'; img-src 'self' data:; media-src 'self'; object-src 'none'; "
    "base-uri 'none'; frame-ancestors 'none'",
    "X-Content-Type-Options": "nosniff",
    "Referrer-Policy": "no-referrer",
}
