"""The labeling web app through HTTP (FastAPI's TestClient): authentication, CSRF, roles, cross-user writes,
bad input that writes nothing, and the health and schema endpoints."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest
from builders import PASSWORD, add_user, labels_body, make_label_dataset
from fastapi.testclient import TestClient
from page_modules import page_files
from sqlalchemy import func, select

import langtraj.labeling
from langtraj.labeling.app import CSRF_HEADER, ServerConfig, create_app
from langtraj.labeling.db import Database
from langtraj.labeling.models import Annotation, Choice, Role
from langtraj.labeling.tasks import add_tasks

MARKUP = '<img src=x onerror="alert(1)"><script>document.title="pwned"</script>'


@pytest.fixture
def server(tmp_path: Path):
    dataset = make_label_dataset(tmp_path, num_scenes=2)
    config = ServerConfig(dataset)
    db = Database(config.url)
    add_tasks(db, dataset, overlap=2)
    for name, role in (
        ("ann1", Role.ANNOTATOR),
        ("ann2", Role.ANNOTATOR),
        ("rev", Role.REVIEWER),
        ("boss", Role.ADMIN),
    ):
        add_user(db, name, role)
    yield create_app(config, db), db
    db.dispose()


def login(app, name: str) -> TestClient:  # type: ignore[no-untyped-def]
    client = TestClient(app)
    reply = client.post("/api/login", json={"name": name, "password": PASSWORD})
    assert reply.status_code == 200, reply.text
    client.headers[CSRF_HEADER] = reply.json()["csrf"]
    return client


def submit(client: TestClient, slot: int, sid: str, body: dict) -> object:
    return client.post(f"/api/slots/{slot}/submit", json={**body, "submission_id": sid, "lead_time_ms": 900})


def count(db: Database, table) -> int:  # type: ignore[no-untyped-def]
    with db.session() as session:
        return session.scalar(select(func.count()).select_from(table)) or 0


def test_health_and_openapi(server) -> None:  # type: ignore[no-untyped-def]
    client = TestClient(server[0])
    assert client.get("/healthz").json() == {"status": "ok"}
    paths = client.get("/openapi.json").json()["paths"]
    assert {"/api/login", "/api/tasks/next", "/api/slots/{slot_id}/submit", "/api/review/{task_id}/accept"} <= set(
        paths
    )
    page = client.get("/")
    assert page.status_code == 200 and "text/html" in page.headers["content-type"]
    assert "default-src 'self'" in page.headers["content-security-policy"]


WRITE_BODIES = [None, {}, {"pair": [7, 17]}, {"annotation_id": 1}, {"into_dataset": True}, "garbage", [1, 2, 3]]


def _write_routes(app) -> list[tuple[str, str]]:  # type: ignore[no-untyped-def]
    routes = []
    for route in app.routes:
        for method in getattr(route, "methods", ()) or ():
            if method in ("POST", "PUT", "PATCH", "DELETE") and route.path != "/api/login":
                routes.append(
                    (
                        method,
                        route.path.replace("{slot_id}", "1").replace("{task_id}", "1").replace("{annotation_id}", "1"),
                    )
                )
    return routes


def test_every_write_refuses_unauthenticated_and_forged_requests_whatever_the_body(server) -> None:  # type: ignore[no-untyped-def]
    app, db = server
    routes = _write_routes(app)
    assert len(routes) == 7  # logout, next, submit, release, edit, accept, export
    anonymous = TestClient(app)
    logged_in = login(app, "boss")
    no_csrf = TestClient(app, cookies=logged_in.cookies)
    wrong_csrf = TestClient(app, cookies=logged_in.cookies, headers={CSRF_HEADER: "not-the-token"})
    for method, path in routes:
        for body in WRITE_BODIES:
            kwargs = {"json": body} if not isinstance(body, str) else {"content": body}
            assert anonymous.request(method, path, **kwargs).status_code == 401, (method, path, body)
            assert no_csrf.request(method, path, **kwargs).status_code == 403, (method, path, body)
            assert wrong_csrf.request(method, path, **kwargs).status_code == 403, (method, path, body)
    assert count(db, Annotation) == 0
    assert anonymous.get("/api/tasks/1").status_code == 401


def test_login_logout_and_roles(server) -> None:  # type: ignore[no-untyped-def]
    app, _ = server
    assert TestClient(app).post("/api/login", json={"name": "ann1", "password": "wrong password"}).status_code == 401
    assert TestClient(app).post("/api/login", json={"name": "nobody", "password": PASSWORD}).status_code == 401
    ann = login(app, "ann1")
    assert ann.get("/api/me").json()["role"] == "annotator"
    assert ann.get("/api/review/queue").status_code == 403
    assert ann.post("/api/review/1/accept", json={"annotation_id": 1}).status_code == 403
    assert ann.post("/api/export", json={"into_dataset": False}).status_code == 403
    assert login(app, "rev").get("/api/review/queue").status_code == 200
    assert login(app, "rev").post("/api/export", json={}).status_code == 403
    assert ann.post("/api/logout").status_code == 200
    assert ann.get("/api/me").status_code == 401


def test_an_annotator_cannot_write_another_annotators_labels(server) -> None:  # type: ignore[no-untyped-def]
    app, db = server
    ann1, ann2 = login(app, "ann1"), login(app, "ann2")
    slot = ann1.post("/api/tasks/next").json()["slot_id"]
    assert submit(ann2, slot, "steal-0001", labels_body()).status_code == 403
    assert ann2.post(f"/api/slots/{slot}/release").status_code == 403
    created = submit(ann1, slot, "mine-0001", labels_body())
    assert created.status_code == 201
    annotation = created.json()["annotation_id"]
    assert ann2.put(f"/api/annotations/{annotation}", json=labels_body(subtype_b="other/unknown")).status_code == 403
    assert submit(ann2, slot, "mine-0001", labels_body()).status_code == 409  # another's submission id
    with db.session() as session:
        assert session.scalars(select(Choice.subtype).where(Choice.track_id == 17)).all() == ["yielding/intersection"]
    assert ann1.put(f"/api/annotations/{annotation}", json=labels_body(subtype_b="other/unknown")).status_code == 200


@pytest.mark.parametrize(
    ("body", "status", "message"),
    [
        (labels_body(subtype_b="yielding/on_the_moon"), 422, "not a subtype of the InterDrive taxonomy"),
        (labels_body(subtype_b="made_up"), 422, "not a subtype"),
        (
            {
                "pair": [7, 99],
                "choices": [
                    {"track_id": 7, "other_id": 99, "subtype": "other/unknown"},
                    {"track_id": 99, "other_id": 7, "subtype": "other/unknown"},
                ],
            },
            422,
            "agent 99 is not in this window",
        ),
        ({**labels_body(), "pair": [7, 7]}, 422, "cannot interact with itself"),
        (labels_body(subtype_b="other/undefined"), 422, "needs a description"),
        (labels_body(text="x" * 3000, subtype_b="other/undefined"), 422, ""),
        ({**labels_body(), "choices": labels_body()["choices"][:1]}, 422, "one choice per agent"),
    ],
)
def test_bad_labels_get_a_clear_4xx_and_write_nothing(server, body, status, message) -> None:  # type: ignore[no-untyped-def]
    app, db = server
    ann = login(app, "ann1")
    slot = ann.post("/api/tasks/next").json()["slot_id"]
    reply = submit(ann, slot, "bad-00001", body)
    assert reply.status_code == status, reply.text
    assert message in str(reply.json()["detail"])
    assert count(db, Annotation) == 0 and count(db, Choice) == 0
    assert submit(ann, slot, "good-0001", labels_body()).status_code == 201  # the slot is still held


def test_missing_windows_slots_and_annotations_are_404(server) -> None:  # type: ignore[no-untyped-def]
    ann = login(server[0], "ann1")
    assert ann.get("/api/tasks/999").status_code == 404
    assert ann.get("/api/tasks/999/video").status_code == 404
    assert "no slot 999" in submit(ann, 999, "none-0001", labels_body()).json()["detail"]
    assert ann.put("/api/annotations/999", json=labels_body()).status_code == 404
    rev = login(server[0], "rev")
    assert rev.post("/api/review/999/accept", json={"annotation_id": 1}).status_code == 404


def test_markup_in_free_text_is_stored_verbatim(server) -> None:  # type: ignore[no-untyped-def]
    app, db = server
    ann = login(app, "ann1")
    slot = ann.post("/api/tasks/next").json()["slot_id"]
    assert submit(ann, slot, "markup-001", labels_body("other/undefined", text=MARKUP)).status_code == 201
    with db.session() as session:
        assert session.scalar(select(Choice.text).where(Choice.subtype == "other/undefined")) == MARKUP


def test_taxonomy_endpoint_is_the_taxonomy_module(server) -> None:  # type: ignore[no-untyped-def]
    from langtraj.interdrive.taxonomy import SUBTYPES

    ann = login(server[0], "ann1")
    assert [s["id"] for s in ann.get("/api/taxonomy").json()["subtypes"]] == [s.id for s in SUBTYPES]


def test_video_and_positions_only_for_windows_routed_to_the_annotator(server) -> None:  # type: ignore[no-untyped-def]
    ann = login(server[0], "ann1")
    assert ann.get("/api/tasks/1/video").status_code == 403  # not claimed yet
    assert ann.post("/api/tasks/next").json()["task"]["task_id"] == 1
    assert login(server[0], "ann2").get("/api/tasks/2").status_code == 403
    assert login(server[0], "rev").get("/api/tasks/2").status_code == 200
    video = ann.get("/api/tasks/1/video")
    assert video.status_code == 200 and video.headers["content-type"] == "video/mp4" and video.content[4:8] == b"ftyp"
    positions = ann.get("/api/tasks/1/positions").json()
    assert {a["id"] for a in positions["agents"]} == {7, 17, 27, 37}


def test_no_sql_is_built_by_string_formatting() -> None:
    """Every SQL string the package hands to a driver (execute, text) is a literal, a constant name or psycopg's
    composed SQL, never an f-string, concatenation or str.format."""
    offenders = []
    for path in Path(langtraj.labeling.__file__).parent.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Call) and getattr(node.func, "attr", getattr(node.func, "id", "")) in (
                "execute",
                "text",
            ):
                for arg in node.args[:1]:
                    if isinstance(arg, ast.JoinedStr | ast.BinOp) or (
                        isinstance(arg, ast.Call)
                        and getattr(arg.func, "attr", "") == "format"
                        and isinstance(arg.func.value, ast.Constant)  # psycopg's sql.SQL(...).format composes safely
                    ):
                        offenders.append(f"{path.name}:{node.lineno}")
    assert offenders == []


def test_annotators_see_only_their_own_progress(server) -> None:  # type: ignore[no-untyped-def]
    app, _ = server
    ann1, ann2 = login(app, "ann1"), login(app, "ann2")
    for client, sid in ((ann1, "prog-0001"), (ann2, "prog-0002")):
        assert submit(client, client.post("/api/tasks/next").json()["slot_id"], sid, labels_body()).status_code == 201
    assert ann1.get("/api/progress").json()["per_annotator"] == {"ann1": 1}
    assert login(app, "rev").get("/api/progress").json()["per_annotator"] == {"ann1": 1, "ann2": 1}
    assert ann1.get("/api/progress").json()["tasks_accepted"] == 1


@pytest.mark.parametrize("steps", [{"pair": -5}, {"pair": 1, "coffee": 10}])
def test_step_times_are_the_protocols_steps_and_not_negative(server, steps) -> None:  # type: ignore[no-untyped-def]
    app, db = server
    ann = login(app, "ann1")
    slot = ann.post("/api/tasks/next").json()["slot_id"]
    body = {**labels_body(), "submission_id": "steps-0001", "lead_time_ms": 10, "step_times_ms": steps}
    assert ann.post(f"/api/slots/{slot}/submit", json=body).status_code == 422
    assert count(db, Annotation) == 0


def test_the_page_and_api_are_not_cached_stale(server) -> None:  # type: ignore[no-untyped-def]
    client = TestClient(server[0])
    assert client.get("/").headers["cache-control"] == "no-cache"
    assert client.get("/static/app.js").headers["cache-control"] == "no-cache"


def test_the_page_loads_its_own_files_and_the_shared_ones(server) -> None:  # type: ignore[no-untyped-def]
    """Every file the page loads is served (the shared /common ones too, without logging in) and every name its
    script imports is exported there (tests/page_modules.py)."""
    files = dict(page_files(TestClient(server[0])))
    assert {"/static/app.js", "/static/style.css", "/common/dom.js", "/common/api.js", "/common/base.css"} <= set(files)
    assert all(r.headers["cache-control"] == "no-cache" for r in files.values())
