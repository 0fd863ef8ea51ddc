"""The studio's page files as the app serves them: every stylesheet and module the page loads, and every import
of every module (the shared ones under /common too), resolves to a file the app serves, with the security headers;
every imported name is exported (tests/page_modules.py). The browser tests drive the page itself."""

from __future__ import annotations

from pathlib import Path

from fastapi.testclient import TestClient
from page_modules import page_files

from langtraj.studio.app import StudioConfig, create_app
from langtraj.studio.catalog import Catalog
from langtraj.web import SECURITY_HEADERS


def test_every_file_the_page_loads_is_served_and_every_import_resolves(catalog: Catalog, tmp_path: Path) -> None:
    client = TestClient(create_app(StudioConfig((), data=tmp_path / "data"), catalog))
    files = dict(page_files(client))
    for path in (
        "/static/studio.js",
        "/static/replay.js",
        "/static/plots.js",
        "/common/dom.js",
        "/common/api.js",
        "/common/base.css",
        "/static/style.css",
    ):
        assert path in files, sorted(files)
    for path, response in files.items():
        kind = "javascript" if path.endswith(".js") else "css"
        assert kind in response.headers["content-type"], (path, response.headers["content-type"])
        assert response.headers["content-security-policy"] == SECURITY_HEADERS["Content-Security-Policy"], path
        assert response.headers["cache-control"] == "no-cache", path
