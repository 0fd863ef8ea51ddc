"""Jobs: a real closed-loop job end to end (shipped checkpoint, 2 rollouts, compared with the unprompted run),
its rollouts, video and a suite case; a job stopped mid-run leaves only complete files; jobs survive a restart."""

from __future__ import annotations

import json
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from fastapi.testclient import TestClient

from langtraj.cases import Case
from langtraj.errors import InputError
from langtraj.rollouts.container import Rollouts
from langtraj.studio.app import StudioConfig, create_app
from langtraj.studio.cases import case_of
from langtraj.studio.catalog import Catalog
from langtraj.studio.jobs import INTERRUPTED, Job, JobBoard, JobSpec, JobStore
from langtraj.studio.simulation import RESULT_FILE, ROLLOUTS_FILE, JobRunner
from langtraj.suites.config import load_suite

WOMD_ID = "637f20cafde22ff8"
PROMPTS = ["@1580 yields to @1584", "@1588 comes to a stop"]


@pytest.fixture(scope="module")
def womd_key(catalog: Catalog) -> str:
    return next(e.key for e in catalog.entries if e.scenario_id == WOMD_ID)


def _wait(client: TestClient, job_id: str, seconds: float = 300) -> dict:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        job = client.get(f"/api/jobs/{job_id}").json()
        if job["status"] not in ("queued", "running"):
            return job
        time.sleep(0.5)
    raise AssertionError(f"job {job_id} did not finish in {seconds} s")


@pytest.mark.slow  # about 150 s; the browser test runs a real job through the same API by default
def test_a_real_job_end_to_end(catalog: Catalog, womd_key: str, tmp_path: Path) -> None:
    """A job under the IDM planner (the default), saved as a case that `langtraj test --planner idm` replays: the
    same positions as the watched rollout, and its prompts judged followed."""
    app = create_app(StudioConfig((), data=tmp_path), catalog)
    client = TestClient(app)
    try:
        created = client.post("/api/jobs", json={"scene": womd_key, "prompts": PROMPTS, "rollouts": 2, "seed": 3})
        assert created.status_code == 201, created.text
        job_id = created.json()["job"]["id"]
        assert created.json()["job"]["status"] == "queued"
        assert client.get(f"/api/jobs/{job_id}/rollouts.npz").status_code == 404  # nothing before its first run ends
        job = _wait(client, job_id)
    finally:
        app.state.board.close()
    assert (job["status"], job["progress"], job["error"], job["case"]["seeds"]) == ("done", 1.0, None, [3, 4])
    assert job["planner"] == "idm" and job["case"]["criteria"]["terminate_on_collision"] is False
    assert job["started"] and job["finished"]
    result = job["result"]
    assert (result["start_step"], result["step_seconds"]) == (10, 0.1)
    prompted, unprompted = result["runs"]["prompted"], result["runs"]["unprompted"]
    for run in (prompted, unprompted):
        assert len(run["rollouts"]) == 2
        xs = run["rollouts"][0]["x"]
        assert len(xs) == 50 and all(len(v) == 80 for v in xs.values())
        assert [p["text"] for p in run["prompts"]] == PROMPTS
        assert [(p["agent"], p["other"], p["behaviour"]) for p in run["prompts"]] == [
            (1580, 1584, "yield"),
            (1588, None, "stop"),
        ]
        assert all(len(p["followed"]) == 2 and all(isinstance(f, bool) for f in p["followed"]) for p in run["prompts"])
        assert len(run["agents"]) == 50 and all(len(a["collision"]) == 2 for a in run["agents"])
        assert 0 < run["realism"]["meta_metric"] < 1
    assert {t["track_id"] for t in prompted["targets"]} == {1580, 1588} and unprompted["targets"] == []
    assert prompted["prompts"][1]["followed"] == [True, True]  # the stop is kept in both rollouts
    listed = client.get("/api/jobs").json()["jobs"]
    assert [j["id"] for j in listed] == [job_id] and "result" not in listed[0]

    npz = client.get(f"/api/jobs/{job_id}/rollouts.npz")
    assert npz.status_code == 200
    (tmp_path / "down.npz").write_bytes(npz.content)
    rollouts = Rollouts.load(tmp_path / "down.npz")
    assert rollouts.x.shape == (2, 50, 80)
    first = prompted["rollouts"][0]["x"]["1580"]
    assert np.allclose(rollouts.x[0, list(rollouts.object_id).index(1580)], first, atol=0.006)

    video = client.get(f"/api/jobs/{job_id}/video.mp4")
    assert video.status_code == 200 and video.content[4:8] == b"ftyp"
    assert (tmp_path / "jobs" / job_id / "video.mp4").read_bytes() == video.content

    saved = client.post(f"/api/jobs/{job_id}/case", json={"suite": "smoke", "name": "yield-stop"})
    assert saved.status_code == 200, saved.text
    suite = load_suite(saved.json()["suite"])
    (case,) = suite.cases
    assert (case.name, case.index, case.window, case.prompts, case.seeds) == (
        "yield-stop",
        0,
        None,
        tuple(PROMPTS),
        (3, 4),
    )
    assert case.scenario.name == "motion_data_one_scenario.tfrecord"
    assert saved.json()["command"].startswith(f"langtraj test {saved.json()['suite']} --planner idm")
    _replays(case, rollouts, prompted, tmp_path)
    again = client.post(f"/api/jobs/{job_id}/case", json={"suite": "smoke", "name": "yield-stop"})
    assert again.status_code == 409 and "yield-stop" in again.json()["error"]
    bad = client.post(f"/api/jobs/{job_id}/case", json={"suite": "smoke", "name": "x", "criteria": {"min_ttc": -1}})
    assert bad.status_code == 400 and "min_ttc" in bad.json()["error"]
    assert len(load_suite(tmp_path / "suites" / "smoke.yaml").cases) == 1  # the refused case left it as it was
    assert client.post(f"/api/jobs/{job_id}/case", json={"suite": "../up", "name": "x"}).status_code == 400


def _replays(case, watched: Rollouts, prompted: dict, tmp_path: Path) -> None:
    """The saved case's first seed run as `langtraj test` runs it gives the watched rollout 0 to 1e-4 m, with the
    prompts' verdicts the studio showed."""
    from langtraj.suites.episode import EpisodeTask, run_episode

    kept: list[Rollouts] = []
    task = EpisodeTask("smoke", case, case.seeds[0], "idm", None, 10.0, tmp_path / "test", video=False)
    result = run_episode(task, lambda env: kept.append(env.rollout()))
    (replayed,) = kept
    assert list(replayed.object_id) == list(watched.object_id)
    assert np.abs(replayed.x[0] - watched.x[0]).max() < 1e-4 and np.abs(replayed.y[0] - watched.y[0]).max() < 1e-4
    followed = [p["followed"][0] for p in prompted["prompts"]]
    assert [p["followed"] for p in result.prompts] == followed
    assert result.status != "error", result.reasons


def test_a_job_that_simulated_the_ego_cannot_be_kept() -> None:
    job = Job("j", JobSpec("s0", WOMD_ID, Case(prompts=("@1 stops",)), planner=None))
    with pytest.raises(InputError, match="simulated every agent, the ego too"):
        case_of(job, "kept", None)


@pytest.mark.slow  # 40 s; test_server_stop's ctrl-c case stops a real job mid-run and checks its files by default
def test_a_job_stopped_mid_run_leaves_only_complete_files(catalog: Catalog, womd_key: str, tmp_path: Path) -> None:
    real = JobRunner(catalog)

    def runner(job: Job, folder: Path, report, stop: threading.Event) -> None:
        def report_and_stop(progress: float, stage: str) -> None:
            report(progress, stage)
            if stage.startswith("unprompted run 2/"):  # the studio stops while the second run simulates
                stop.set()

        real(job, folder, report_and_stop, stop)

    board = JobBoard(JobStore(tmp_path / "jobs"), runner)
    entry = catalog.entry(womd_key)
    case = Case(scenario=entry.file, index=entry.index, prompts=tuple(PROMPTS))
    spec = JobSpec(womd_key, WOMD_ID, case, rollouts=2)
    job = board.run(board.submit(spec))
    assert (job.status, job.error) == ("interrupted", INTERRUPTED)
    folder = board.folder(job.id)
    assert sorted(p.name for p in folder.iterdir()) == ["job.json", ROLLOUTS_FILE]  # no result, no temporary file
    assert json.loads((folder / "job.json").read_text())["status"] == "interrupted"
    assert Rollouts.load(folder / ROLLOUTS_FILE).num_rollouts == 2


def _record(store: JobStore, job_id: str, status: str, created: str) -> None:
    store.save(Job(job_id, JobSpec("s0", WOMD_ID, Case(prompts=("@1 stops",))), status=status, created=created))


def test_jobs_survive_a_restart(catalog: Catalog, tmp_path: Path) -> None:
    store = JobStore(tmp_path / "jobs")
    _record(store, "a-done", "done", "2027-01-01T10:00:00+00:00")
    _record(store, "b-running", "running", "2027-01-01T11:00:00+00:00")
    _record(store, "c-queued", "queued", "2027-01-01T12:00:00+00:00")
    stray = store.folder("b-running") / ".result.json.x1y2.tmp.json"
    stray.write_text('{"half')  # what a killed process leaves behind
    ran: list[str] = []

    def runner(job: Job, folder: Path, report, stop) -> None:
        ran.append(job.id)
        report(0.5, "half way")

    app = create_app(StudioConfig((), data=tmp_path), catalog, runner)
    client = TestClient(app)
    try:
        job = _wait(client, "c-queued", 30)
    finally:
        app.state.board.close()
    assert ran == ["c-queued"] and job["status"] == "done"
    listed = client.get("/api/jobs").json()["jobs"]
    assert [j["id"] for j in listed] == ["c-queued", "b-running", "a-done"]
    interrupted = listed[1]
    assert (interrupted["status"], interrupted["error"]) == ("interrupted", INTERRUPTED)
    assert not stray.exists()
    assert json.loads((store.folder("b-running") / "job.json").read_text())["status"] == "interrupted"
    assert client.get("/api/jobs/a-done/rollouts.npz").status_code == 404  # done on record, but no file: 404
    assert client.get("/api/jobs/b-running/video.mp4").status_code == 404
    assert client.get("/api/jobs/nope").status_code == 404
    assert not (store.folder("c-queued") / RESULT_FILE).exists()


def test_jobs_submitted_within_one_second_list_newest_first(tmp_path: Path) -> None:
    board = JobBoard(JobStore(tmp_path / "jobs"), lambda job, folder, report, stop: None)
    spec = JobSpec("s0", WOMD_ID, Case(prompts=("@1 stops",)))
    submitted = [board.submit(spec).id for _ in range(5)]  # well within a second: the ids' random tails decide nothing
    assert [j.id for j in board.jobs()] == submitted[::-1]
    reloaded = JobBoard(JobStore(tmp_path / "jobs"), lambda job, folder, report, stop: None)
    assert [j.id for j in reloaded.jobs()] == submitted[::-1]


def test_an_interrupted_job_is_submitted_again_with_its_spec(catalog: Catalog, womd_key: str, tmp_path: Path) -> None:
    store = JobStore(tmp_path / "jobs")
    spec = JobSpec(womd_key, WOMD_ID, Case(prompts=("@1588 comes to a stop",), seeds=(5, 6)), 2, planner="idm")
    store.save(Job("a-interrupted", spec, status="interrupted", error=INTERRUPTED))
    store.save(Job("b-done", spec, status="done"))
    client = TestClient(create_app(StudioConfig((), data=tmp_path), catalog, _no_run, start_worker=False))
    again = client.post("/api/jobs/a-interrupted/resubmit")
    assert again.status_code == 201, again.text
    job = again.json()["job"]
    assert job["id"] != "a-interrupted" and job["status"] == "queued"
    assert (job["planner"], job["rollouts"], job["case"]["seeds"], job["case"]["prompts"]) == (
        "idm",
        2,
        [5, 6],
        ["@1588 comes to a stop"],
    )
    done = client.post("/api/jobs/b-done/resubmit")
    assert done.status_code == 409 and "only an interrupted or failed job" in done.json()["error"]
    assert client.post("/api/jobs/nope/resubmit").status_code == 404


def _no_run(*_args) -> None:
    raise AssertionError("no job runs in this test")
