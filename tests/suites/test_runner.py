"""A suite over an executor: results.json as episodes finish, report.md and junit.xml, bad planners failing only
their case."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET

import pytest

from langtraj.errors import InputError
from langtraj.suites import RunOptions, check_run, load_suite, run_suite
from suites.conftest import write_suite
from suites.fakes import FAKE_ENV, write_scene


def _options(tmp_path, planner="suites.fakes:GoodPlanner", **kw) -> RunOptions:
    return RunOptions(out=tmp_path / "out", planner=planner, env=FAKE_ENV, video=False, **kw)


def _junit_cases(out) -> tuple[ET.Element, dict[str, ET.Element]]:
    root = ET.parse(out / "junit.xml").getroot()
    suite = root.find("testsuite")
    return suite, {c.get("name"): c for c in suite.iter("testcase")}


@pytest.mark.parametrize(
    ("planner", "reason", "timeout"),
    [
        ("RaisingPlanner", "planner raised ValueError: boom at step 3", 10.0),
        ("NaNPlanner", "planner returned a non-finite action at step 12", 10.0),
        ("WrongShapePlanner", "planner returned an action of shape (3,), expected (2,) at step 1", 10.0),
        ("HangingPlanner", "planner timed out after 1 s at step 2", 1.0),
    ],
)
def test_a_bad_planner_fails_its_case_and_the_other_passes(tmp_path, two_case_suite, planner, reason, timeout):
    options = _options(tmp_path, f"suites.fakes:{planner}", step_timeout=timeout)
    results = run_suite(load_suite(two_case_suite), options)
    assert results.case_statuses() == {"good-case": "pass", "bad-case": "fail"}
    saved = json.loads((options.out / "results.json").read_text())
    assert saved["complete"] and saved["finished"]
    assert [(e["case"], e["status"], e["reasons"]) for e in saved["episodes"]] == [
        ("good-case", "pass", []),
        ("bad-case", "fail", [reason]),
    ]
    suite, cases = _junit_cases(options.out)
    assert (suite.get("name"), suite.get("tests"), suite.get("failures"), suite.get("errors")) == (
        "fake",
        "2",
        "1",
        "0",
    )
    assert cases["good-case[seed0]"].find("failure") is None and cases["good-case[seed0]"].get("classname") == "fake"
    failure = cases["bad-case[seed0]"].find("failure")
    assert failure.get("message") == reason
    assert ("Traceback" in failure.text) == (planner == "RaisingPlanner")  # the planner's own, for its author
    report = (options.out / "report.md").read_text()
    assert "**FAIL: 1 of 2 cases failed, 0 with errors (1 of 2 episodes passed)" in report
    assert "## bad-case: FAIL" in report and reason in report and "## good-case: PASS" in report


def test_results_are_written_as_episodes_finish(tmp_path, two_case_suite):
    options = _options(tmp_path)
    seen = []

    def look(result):
        seen.append(json.loads((options.out / "results.json").read_text()))
        if len(seen) == 2:
            raise KeyboardInterrupt  # the run dies after two episodes

    suite = load_suite(two_case_suite).with_seeds(2)
    with pytest.raises(KeyboardInterrupt):
        run_suite(suite, options, on_result=look)
    assert [len(s["episodes"]) for s in seen] == [1, 2] and not seen[0]["complete"]
    saved = json.loads((options.out / "results.json").read_text())
    assert len(saved["episodes"]) == 2 and not saved["complete"] and saved["finished"] is None
    assert saved["summary"]["finished"] == 2 and saved["summary"]["episodes"] == 4
    assert "only 2 of 4 episodes finished" in (options.out / "report.md").read_text()
    _, cases = _junit_cases(options.out)
    assert cases["good-case[seed0]"].find("skipped") is None and cases["bad-case[seed1]"].find("skipped") is not None


def test_seeds_cases_and_errors_in_the_reports(tmp_path):
    write_scene(tmp_path, "good")
    write_scene(tmp_path, "crash", collide_at=5, at_fault=True, collided_with=[42])
    write_scene(tmp_path, "broken", error_at=3)
    path = write_suite(
        tmp_path,
        [
            {"name": "ok", "scenario": "good.json", "seeds": [0, 1, 2], "window": 1},
            {"name": "crash", "scenario": "crash.json", "seeds": 2},
            {"name": "broken", "scenario": "broken.json"},
        ],
    )
    options = _options(tmp_path, workers=2)  # a pool of two spawned processes
    results = run_suite(load_suite(path), options)
    assert results.case_statuses() == {"ok": "pass", "crash": "fail", "broken": "error"}
    saved = json.loads((options.out / "results.json").read_text())
    assert [(e["case"], e["seed"]) for e in saved["episodes"]] == [
        ("ok", 0), ("ok", 1), ("ok", 2), ("crash", 0), ("crash", 1), ("broken", 0)
    ]  # fmt: skip
    assert saved["summary"] | {"seconds": 0} == {
        "episodes": 6, "finished": 6, "passed": 3, "failed": 2, "errors": 1, "not_happened": 0,
        "cases": 3, "cases_passed": 1, "cases_failed": 1, "cases_errors": 1, "cases_not_happened": 0, "seconds": 0,
        "traffic_collisions": 0, "traffic_offroad": 0, "traffic_episodes": 0, "traffic_flagged": 0,
        "traffic_flagged_failed": 0,
    }  # fmt: skip
    crash = saved["episodes"][3]
    assert crash["figures"]["first_at_fault_step"] == 5 and crash["figures"]["at_fault_with"] == [42]
    suite, cases = _junit_cases(options.out)
    assert (suite.get("tests"), suite.get("failures"), suite.get("errors")) == ("6", "2", "1")  # one per episode
    for seed in (0, 1):
        assert cases[f"crash[seed{seed}]"].find("failure").get("message") == "at-fault collision with 42 at step 5"
    assert all(cases[f"ok[seed{seed}]"].find("failure") is None for seed in (0, 1, 2))
    error = cases["broken[seed0]"].find("error")
    assert error.get("message") == "LangTraj raised RuntimeError: the fake env broke at step 3"
    assert "Traceback" in error.text
    assert float(suite.get("time")) > 0 and all(float(c.get("time")) > 0 for c in cases.values())
    report = (options.out / "report.md").read_text()
    assert "| 1 | FAIL | step 5 (42) | step 5 (42) | no | 5.00 | 0.06 |" in report
    assert "`good.json` (index 0, window 1), ego the env's choice." in report


def test_failed_episodes_videos_are_linked(tmp_path):
    write_scene(tmp_path, "crash", collide_at=3, at_fault=True)
    path = write_suite(tmp_path, [{"name": "crash", "scenario": "crash.json"}])
    options = RunOptions(out=tmp_path / "out", planner="suites.fakes:GoodPlanner", env=FAKE_ENV)
    run_suite(load_suite(path), options)
    assert (options.out / "videos" / "crash-seed0.mp4").is_file()
    assert "([video](videos/crash-seed0.mp4))" in (options.out / "report.md").read_text()


def test_a_dead_worker_leaves_errors_not_a_crash(tmp_path):
    write_scene(tmp_path, "good")
    write_scene(tmp_path, "deadly", exit_at=2)
    path = write_suite(
        tmp_path, [{"name": "deadly", "scenario": "deadly.json"}, {"name": "ok", "scenario": "good.json"}]
    )
    options = _options(tmp_path, workers=2)
    results = run_suite(load_suite(path), options)
    assert results.complete and results.case_statuses()["deadly"] == "error"
    lost = results.episodes[("deadly", 0)]
    assert lost.reasons[0].startswith("the worker was lost (BrokenProcessPool")
    saved = json.loads((options.out / "results.json").read_text())
    assert saved["complete"] and len(saved["episodes"]) == 2


def test_on_a_local_ray_cluster_a_case_that_kills_its_worker_is_lost_alone(tmp_path):
    ray = pytest.importorskip("ray", reason="Ray is optional: pip install 'langtraj[ray]' (CI installs it)")
    write_scene(tmp_path, "good")
    write_scene(tmp_path, "deadly", exit_at=2)
    write_scene(tmp_path, "crash", collide_at=5, at_fault=True)
    path = write_suite(
        tmp_path,
        [
            {"name": "deadly", "scenario": "deadly.json"},
            {"name": "ok", "scenario": "good.json", "seeds": 2},
            {"name": "crash", "scenario": "crash.json"},
        ],
    )
    options = _options(tmp_path, executor="ray", workers=2)  # workers import suites.fakes from this test's path
    try:
        results = run_suite(load_suite(path), options)
    finally:
        ray.shutdown()
    assert results.complete
    assert results.case_statuses() == {"deadly": "error", "ok": "pass", "crash": "fail"}
    (reason,) = results.episodes[("deadly", 0)].reasons
    assert reason.startswith("the worker was lost (") and "WorkerCrashedError" in reason
    saved = json.loads((options.out / "results.json").read_text())
    assert saved["complete"] and saved["summary"]["passed"] == 2 and saved["summary"]["errors"] == 1


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"planner": "no_such_planner"}, "--planner: unknown planner 'no_such_planner'"),
        ({"planner": "suites.fakes:Nothing"}, "has no 'Nothing'"),
        ({"planner": "suites.fakes:BadKindPlanner"}, "action_kind 'teleport'"),
        (
            {"planner": None, "planner_cmd": "no-such-program-x --serve"},
            "--planner-cmd: no program 'no-such-program-x'",
        ),
        ({"planner": None, "planner_cmd": "'unclosed"}, "--planner-cmd: cannot split"),
        ({"planner": None}, "exactly one of --planner and --planner-cmd"),
        ({"executor": "cloud"}, "--executor: unknown executor 'cloud'"),
        ({"workers": 0}, "--workers: must be >= 1"),
        ({"step_timeout": 0}, "--step-timeout: must be > 0"),
    ],
)
def test_bad_options_are_refused_before_anything_is_written(tmp_path, two_case_suite, options, message):
    run = _options(tmp_path, **{"planner": "suites.fakes:GoodPlanner", **options})
    with pytest.raises(InputError, match=message.replace("(", r"\(").replace(")", r"\)")):
        check_run(run)
    with pytest.raises(InputError):
        run_suite(load_suite(two_case_suite), run)
    assert not run.out.exists()


def test_a_log_replay_planner_is_flagged_as_a_baseline(tmp_path, two_case_suite):
    options = _options(tmp_path, "log_replay")
    run_suite(load_suite(two_case_suite), options)
    saved = json.loads((options.out / "results.json").read_text())
    assert [e["reads_log"] for e in saved["episodes"]] == [True, True]
    assert "a log-replay baseline, not a planner under test" in (options.out / "report.md").read_text()
    plain = _options(tmp_path / "plain")
    run_suite(load_suite(two_case_suite), plain)
    assert not any(e["reads_log"] for e in json.loads((plain.out / "results.json").read_text())["episodes"])
    assert "log-replay baseline" not in (plain.out / "report.md").read_text()


def test_a_collision_that_fails_nothing_is_reported_with_its_video(tmp_path):
    """A bystander runs into the ego (not its fault): the case passes, and the collision is there to see."""
    write_scene(tmp_path, "bumped", collide_at=12, collided_with=[42], steps=20)
    path = write_suite(tmp_path, [{"name": "bumped", "scenario": "bumped.json"}])
    options = RunOptions(out=tmp_path / "out", planner="suites.fakes:GoodPlanner", env=FAKE_ENV)
    results = run_suite(load_suite(path), options)
    assert results.case_statuses() == {"bumped": "pass"}
    (episode,) = json.loads((options.out / "results.json").read_text())["episodes"]
    assert episode["figures"]["collisions"] == [{"step": 12, "with": 42, "kind": "rear", "at_fault": False}]
    assert episode["video"] == "videos/bumped-seed0.mp4" and (options.out / episode["video"]).is_file()
    report = (options.out / "report.md").read_text()
    assert "Collision, seed 0: step 12 with 42 (rear, not the ego's fault) ([video](videos/bumped-seed0.mp4))" in report


def test_a_collision_decided_by_right_of_way_says_what_decided_it(tmp_path):
    """A car that ran its red light crosses into the ego: not its fault, and the report says the signal decided."""
    contact = {"kind": "crossed", "right_of_way": "signal"}
    write_scene(tmp_path, "runner", collide_at=30, collided_with=[9], steps=40, contact=contact)
    path = write_suite(tmp_path, [{"name": "runner", "scenario": "runner.json"}])
    options = RunOptions(out=tmp_path / "out", planner="suites.fakes:GoodPlanner", env=FAKE_ENV)
    assert run_suite(load_suite(path), options).case_statuses() == {"runner": "pass"}
    (episode,) = json.loads((options.out / "results.json").read_text())["episodes"]
    assert episode["figures"]["collisions"] == [
        {"step": 30, "with": 9, "kind": "crossed", "at_fault": False, "right_of_way": "signal"}
    ]
    report = (options.out / "report.md").read_text()
    assert "step 30 with 9 (crossed, right of way by signal, not the ego's fault)" in report
