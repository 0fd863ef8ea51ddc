"""Prompt checks: a read prompt with its target, and each way a prompt cannot be run, each with a clear one-line
error; `POST /api/jobs` refuses any of them and creates no job."""

from __future__ import annotations

from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from langtraj.sim.prompt_checks import MAX_PROMPT_CHARS
from langtraj.studio.app import StudioConfig, create_app
from langtraj.studio.catalog import Catalog

WOMD_ID = "637f20cafde22ff8"
YIELD = "@1580 yields to @1584"  # read, and the map gives the yield a path
LEFT = "@1587 turns left at the next intersection"  # its lane allows only a right turn at the next junction


def _runner(*_args) -> None:  # no job may ever run in these tests
    raise AssertionError("a refused job ran")


@pytest.fixture
def client(catalog: Catalog, tmp_path: Path) -> TestClient:
    return TestClient(create_app(StudioConfig((), data=tmp_path / "data"), catalog, _runner, start_worker=False))


@pytest.fixture(scope="module")
def womd_key(catalog: Catalog) -> str:
    return next(e.key for e in catalog.entries if e.scenario_id == WOMD_ID)


def _check(client: TestClient, key: str, prompts: list[str], **pair) -> dict:
    response = client.post(f"/api/scenes/{key}/prompts", json={"prompts": prompts, **pair})
    assert response.status_code == 200, response.text
    return response.json()


def test_a_read_prompt_with_its_target(client: TestClient, womd_key: str) -> None:
    body = _check(client, womd_key, [YIELD, "@1588 comes to a stop"])
    assert body["ok"] and body["error"] is None
    pair, stop = body["prompts"]
    assert (pair["ok"], pair["feasible"], pair["warning"], pair["error"]) == (True, True, None, None)
    assert pair["reading"]["behaviour"] == "yield" and (pair["reading"]["agent"], pair["reading"]["other"]) == (
        1580,
        1584,
    )
    assert pair["reading"]["describe"].startswith("read as: @1580 yield @1584")
    target = pair["target"]
    assert (target["agent"], target["behaviour"], target["other"]) == (1580, "yield", 1584)
    assert len(target["path"]) > 2 and all(len(p) == 2 for p in target["path"])
    assert stop["target"]["stop"] is not None and stop["target"]["behaviour"] == "stop"


def test_an_unread_prompt_is_runnable_without_a_target(client: TestClient, womd_key: str) -> None:
    (check,) = _check(client, womd_key, ["@1580 does a little dance"])["prompts"]
    assert check["ok"] and check["reading"]["behaviour"] is None and check["feasible"] is None
    assert check["reading"]["describe"].startswith("not read:")


def test_a_behaviour_the_map_rules_out_is_warned_about_as_simulate_does(client: TestClient, womd_key: str) -> None:
    """Not refused: `simulate` warns and runs, and a suite reports the scenario as not happened."""
    body = _check(client, womd_key, [f"@1588 comes to a stop. {LEFT}"])
    (check,) = body["prompts"]
    assert body["ok"] and check["ok"] and check["feasible"] is False
    assert "@1587 cannot turn left: no left turn from its lane" in check["warning"]
    stop, left = check["readings"]
    assert (stop["agent"], stop["behaviour"], left["agent"], left["behaviour"]) == (1588, "stop", 1587, "turn_left")
    assert [t["agent"] for t in check["targets"]] == [1588]


def _not_valid_now(client: TestClient, key: str) -> int:
    agents = client.get(f"/api/scenes/{key}").json()["agents"]
    return next(a["id"] for a in agents if not a["sim"])


@pytest.mark.parametrize(
    ("prompts", "expected"),
    [
        ([""], "empty prompt"),
        (["x" * 10_000], f"prompt is 10000 characters long; the limit is {MAX_PROMPT_CHARS}"),
        (["@99999 stops"], "unknown agent @99999"),
        (["the red car stops"], "mentions no agent"),
        (["@1580 yields to @1580"], "names @1580 twice"),
        (["@1580 yeilds to @1584"], "did you mean '@1580 yields to @1584'?"),
        (["@1580 slows down. @1584 trun left"], "did you mean '@1584 turn left'?"),
        ([YIELD, "@1584 speeds up"], "@1584 is named by prompt 1 too"),
        (["NOT_VALID stops"], "not valid at the current step"),
    ],
)
def test_prompts_that_cannot_run_are_refused_with_no_job(
    client: TestClient, womd_key: str, prompts: list[str], expected: str
) -> None:
    if prompts == ["NOT_VALID stops"]:
        prompts = [f"@{_not_valid_now(client, womd_key)} stops"]
    body = _check(client, womd_key, prompts)
    assert not body["ok"]
    refused = [p for p in body["prompts"] if not p["ok"]]
    assert len(refused) == 1 and expected in refused[0]["error"]
    assert "\n" not in refused[0]["error"]
    response = client.post("/api/jobs", json={"scene": womd_key, "prompts": prompts, "rollouts": 2})
    assert response.status_code == 400 and expected in response.json()["error"]
    assert client.get("/api/jobs").json() == {"jobs": []}


def test_the_long_prompt_never_reaches_the_reader(
    client: TestClient, womd_key: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    import langtraj.sim.prompt_checks as checks

    def refuse(*_args):
        raise AssertionError("read")

    monkeypatch.setattr(checks, "user_prompt_entry", refuse)
    monkeypatch.setattr(checks, "read_prompts", refuse)
    (check,) = _check(client, womd_key, ["@1580 stops " * 1000])["prompts"]
    assert not check["ok"] and check["reading"] is None


@pytest.mark.parametrize(
    ("pair", "expected"),
    [
        ({"adversary": 1580}, "an adversary needs a target"),
        ({"adversary": 1580, "target": 1580}, "the same agent (@1580)"),
        ({"adversary": 1580, "target": 99999}, "@99999 is not an agent of this scene at its current step"),
    ],
)
def test_collision_pair_problems(client: TestClient, womd_key: str, pair: dict, expected: str) -> None:
    body = _check(client, womd_key, [], **pair)
    assert not body["ok"] and expected in body["error"]
    response = client.post("/api/jobs", json={"scene": womd_key, "prompts": [], **pair})
    assert response.status_code == 400 and expected in response.json()["error"]


def test_bad_job_bodies_get_one_line(client: TestClient, womd_key: str) -> None:
    for body, expected in (
        ({"scene": womd_key, "rollouts": 17}, "rollouts"),
        ({"scene": womd_key, "rollouts": 0}, "rollouts"),
        ({"prompts": [YIELD]}, "scene"),
        ({"scene": womd_key, "colour": "red"}, "colour"),
    ):
        response = client.post("/api/jobs", json=body)
        assert response.status_code == 400 and expected in response.json()["error"], response.text
    assert client.post("/api/jobs", json={"scene": "nope"}).status_code == 404
    big = client.post("/api/jobs", content=b"{" + b" " * 300_000 + b"}", headers={"content-type": "application/json"})
    assert big.status_code == 413
    assert client.get("/api/jobs").json() == {"jobs": []}


def test_a_prompt_of_the_ego_is_refused_as_the_env_refuses_it(client: TestClient, womd_key: str) -> None:
    """With a planner (IDM by default) the scene's self-driving car is the ego, which no prompt may steer: the
    check is the env's own, so a saved case never fails in `langtraj test` for it. Every agent simulated: allowed."""
    ego = next(a["id"] for a in client.get(f"/api/scenes/{womd_key}").json()["agents"] if a["sdc"])
    text = f"@{ego} slows down"
    (check,) = _check(client, womd_key, [text])["prompts"]
    assert not check["ok"] and check["error"] == f"{text!r} asks something of the ego, which the planner drives"
    response = client.post("/api/jobs", json={"scene": womd_key, "prompts": [text]})
    assert response.status_code == 400 and "asks something of the ego" in response.json()["error"]
    (free,) = _check(client, womd_key, [text], planner=None)["prompts"]
    assert free["ok"]
    unknown = client.post(f"/api/scenes/{womd_key}/prompts", json={"prompts": [text], "planner": "nope"})
    assert unknown.status_code == 400 and "planner" in unknown.json()["error"]


def test_a_job_that_would_run_the_same_simulation_twice_is_refused(client: TestClient, womd_key: str) -> None:
    response = client.post("/api/jobs", json={"scene": womd_key})
    assert (
        response.status_code == 400 and "the run and its comparison would be the same run" in response.json()["error"]
    )
    assert client.get("/api/jobs").json() == {"jobs": []}
