"""What the page tests of LangTraj's web apps share without a browser: every file a page loads (its stylesheets and
module scripts, and each module's imports, followed) fetched from the app, and every name a module imports checked
against what the imported module exports, so a mistyped path or name fails here rather than in the browser."""

from __future__ import annotations

import re
from collections.abc import Iterator
from typing import Any

_IMPORT = re.compile(r"^import\s*\{([^}]*)\}\s*from\s*'([^']+)';", re.M)
_EXPORT = re.compile(r"^export\s+(?:async\s+)?(?:function|const|let|class)\s+([A-Za-z_$][\w$]*)", re.M)
_LOADS = re.compile(r'<(?:link rel="stylesheet"|script type="module") (?:href|src)="([^"]+)"')


def _resolve(base: str, path: str) -> str:
    if path.startswith("/"):
        return path
    folder = base.rsplit("/", 1)[0]
    return f"{folder}/{path[2:] if path.startswith('./') else path}"


def page_files(client: Any, page: str = "/") -> Iterator[tuple[str, Any]]:
    """(path, response) of each file `page` loads, its modules' imports followed; each import's names checked
    against the imported module's exports (AssertionError naming the module and the name)."""
    html = client.get(page)
    assert html.status_code == 200, (page, html.status_code)
    todo = list(_LOADS.findall(html.text))
    seen: dict[str, Any] = {}
    wanted: list[tuple[str, str, set[str]]] = []
    while todo:
        path = todo.pop()
        if path in seen:
            continue
        response = client.get(path)
        assert response.status_code == 200, (path, response.status_code)
        seen[path] = response
        if path.endswith(".js"):
            for names, source in _IMPORT.findall(response.text):
                target = _resolve(path, source)
                wanted.append((path, target, {n.strip().split(" as ")[0] for n in names.split(",") if n.strip()}))
                todo.append(target)
    for importer, target, names in wanted:
        exported = set(_EXPORT.findall(seen[target].text))
        missing = names - exported
        assert not missing, f"{importer} imports {sorted(missing)} that {target} does not export"
    yield from seen.items()
