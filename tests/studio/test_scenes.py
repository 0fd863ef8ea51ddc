"""The scene list, its search and filters, the file that fails to load, and the scene view."""

from __future__ import annotations

import re
from pathlib import Path

from fastapi.testclient import TestClient

from langtraj.studio.app import StudioConfig, create_app
from langtraj.studio.catalog import Catalog

from .conftest import CORRUPT_NAME

WOMD_ID = "637f20cafde22ff8"


def _client(catalog: Catalog, tmp_path: Path) -> TestClient:
    return TestClient(create_app(StudioConfig((), data=tmp_path / "data"), catalog))


def test_scene_list_with_windows_kinds_and_the_corrupt_file(catalog: Catalog, tmp_path: Path) -> None:
    body = _client(catalog, tmp_path).get("/api/scenes").json()
    scenes = body["scenes"]
    assert len({s["key"] for s in scenes}) == len(scenes) and all(
        re.fullmatch(r"s[0-9a-f]{12}", s["key"]) for s in scenes
    )
    womd = next(s for s in scenes if s["scenario_id"] == WOMD_ID)
    assert (womd["kind"], womd["window"], womd["steps"], womd["index"]) == ("womd", None, 91, 0)
    assert womd["sim_agents"] <= womd["agents"]
    nuscenes = [s for s in scenes if s["kind"] == "nuscenes"]
    assert nuscenes and all(s["steps"] == 91 and s["window"] is not None for s in nuscenes)
    assert {s["window"] for s in nuscenes if "0061" in s["file"]} == {0, 1}
    assert [e["file"].endswith(CORRUPT_NAME) for e in body["errors"]] == [True]
    assert CORRUPT_NAME in body["errors"][0]["error"] and "\n" not in body["errors"][0]["error"]


def test_scene_search_and_filters(catalog: Catalog, tmp_path: Path) -> None:
    client = _client(catalog, tmp_path)

    def ids(query: str) -> set[str]:
        return {s["scenario_id"] for s in client.get(f"/api/scenes?{query}").json()["scenes"]}

    assert ids("q=637F20") == {WOMD_ID}
    assert ids("q=SCENE-0061") == {"scene-0061_w0", "scene-0061_w91"}
    assert ids("q=motion_data") == {WOMD_ID}
    assert ids("kind=nuscenes") and all(i.startswith("scene-") for i in ids("kind=nuscenes"))
    small = client.get("/api/scenes?max_agents=60").json()["scenes"]
    assert small and all(s["agents"] <= 60 for s in small)
    assert all(s["agents"] >= 150 for s in client.get("/api/scenes?min_agents=150").json()["scenes"])
    assert client.get("/api/scenes?min_agents=lots").status_code == 400


def test_scene_view(catalog: Catalog, tmp_path: Path) -> None:
    client = _client(catalog, tmp_path)
    key = next(e.key for e in catalog.entries if e.scenario_id == WOMD_ID)
    response = client.get(f"/api/scenes/{key}")
    assert response.status_code == 200
    assert response.headers["content-security-policy"].startswith("default-src 'self'")
    view = response.json()
    assert (view["key"], view["scenario_id"], view["current_step"], view["step_seconds"]) == (key, WOMD_ID, 10, 0.1)
    xmin, ymin, xmax, ymax = view["bounds"]
    assert xmin < xmax and ymin < ymax
    agents = view["agents"]
    assert len(agents) == 83 and sum(a["sim"] for a in agents) == 50 and sum(a["sdc"] for a in agents) == 1
    assert {a["type"] for a in agents} <= {"vehicle", "pedestrian", "cyclist", "other"}
    for agent in agents:
        assert len(agent["track"]) == 11
        if agent["sim"]:
            x, y, _ = agent["track"][10]
            assert xmin <= x <= xmax and ymin <= y <= ymax
    kinds = {m["type"] for m in view["map"]}
    assert {"lane", "road_line", "road_edge"} <= kinds
    assert any(m["dashed"] for m in view["map"]) and all(len(m["points"][0]) == 2 for m in view["map"])
    assert all(light["state"] in {"stop", "caution", "go", "unknown"} for light in view["lights"])
    missing = client.get("/api/scenes/nope")
    assert missing.status_code == 404 and "nope" in missing.json()["error"]


def test_scene_keys_are_stable_whatever_else_is_listed(catalog: Catalog, real_data_dir: Path) -> None:
    womd = real_data_dir / "motion_data_one_scenario.tfrecord"
    alone = Catalog.build([womd, womd])  # named twice, listed once
    assert len(alone.entries) == 1
    same = [e for e in catalog.entries if e.file.resolve() == womd.resolve()]
    assert [e.key for e in same] == [alone.entries[0].key]
    assert len({e.key for e in catalog.entries}) == len(catalog.entries)
