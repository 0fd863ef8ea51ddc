"""What a scene can stage, as the studio lists it (`GET /api/scenes/{key}/stagings`): the list `langtraj suggest`
finds (`suggest_stagings`) for the scene and ego, in its order and JSON form, the ego defaulting to the planner's;
bad input (an unknown ego, scene or behaviour) is one line with its status."""

from __future__ import annotations

import pytest
from fastapi.testclient import TestClient

from langtraj.interdrive.behaviour import Behaviour
from langtraj.interdrive.suggest import suggest_stagings
from langtraj.roads import MapIndex
from langtraj.studio.app import StudioConfig, create_app
from langtraj.studio.catalog import Catalog, SceneEntry, read_entry

SCENE_ID = "8a346109094cd5aa"  # WOMD: its self-driving car 1101 faces cut-ins and braking leads
EGO = 1101


@pytest.fixture(scope="module")
def client(catalog: Catalog, tmp_path_factory: pytest.TempPathFactory) -> TestClient:
    data = tmp_path_factory.mktemp("studio-stagings") / "data"
    return TestClient(create_app(StudioConfig((), data=data), catalog, start_worker=False))


@pytest.fixture(scope="module")
def entry(catalog: Catalog) -> SceneEntry:
    return next(e for e in catalog.entries if e.scenario_id == SCENE_ID)


def test_the_list_is_suggest_stagings_for_the_scene_and_ego(client: TestClient, entry: SceneEntry) -> None:
    scenario = read_entry(entry)
    expected = suggest_stagings(
        scenario, ego=EGO, map_index=MapIndex.build(scenario.road_map),
        scene=str(entry.file), index=entry.index, window=entry.window,
    )  # fmt: skip
    response = client.get(f"/api/scenes/{entry.key}/stagings?ego={EGO}")
    assert response.status_code == 200, response.text
    body = response.json()
    assert body["ego"] == EGO
    got = body["stagings"]
    assert [{k: v for k, v in s.items() if k != "typed_prompt"} for s in got] == [s.to_json() for s in expected]
    assert [s["typed_prompt"] for s in got] == [s.typed_prompt for s in expected]
    kinds = {s["behaviour"] for s in got}
    assert {"cut_in", "brake_hard"} <= kinds, kinds
    cut_in = next(s for s in got if s["behaviour"] == "cut_in")
    assert cut_in["typed_prompt"] == cut_in["prompt"].replace("@ego", f"@{EGO}") and f"@{EGO}" in cut_in["typed_prompt"]

    # the planner's ego (the self-driving car) by default, the answer kept; one behaviour or several
    assert client.get(f"/api/scenes/{entry.key}/stagings").json() == body
    only = client.get(f"/api/scenes/{entry.key}/stagings?ego={EGO}&behaviour=cut-in&behaviour=brake_hard").json()
    wanted = {Behaviour.CUT_IN.value, Behaviour.BRAKE_HARD.value}
    assert only["stagings"] == [s for s in got if s["behaviour"] in wanted]


def test_bad_input_is_one_line_with_its_status(client: TestClient, entry: SceneEntry) -> None:
    def error(path: str, status: int) -> str:
        response = client.get(path)
        assert response.status_code == status, (path, response.status_code, response.text)
        line = response.json()["error"]
        assert isinstance(line, str) and "\n" not in line
        return line

    base = f"/api/scenes/{entry.key}/stagings"
    assert error(f"{base}?ego=999999", 400).startswith(f"ego: no track 999999 in scene {SCENE_ID}")
    assert "ego" in error(f"{base}?ego=lots", 400)
    assert "did you mean 'cut_in'" in error(f"{base}?ego={EGO}&behaviour=cutin", 400)
    assert "not a behaviour toward another agent" in error(f"{base}?behaviour=slow_down", 400)
    assert error("/api/scenes/nope/stagings?ego=1", 404) == "no scene 'nope'"
