"""One episode through the fake env: verdicts, planner failures (one-line reasons), env errors, time limits,
videos."""

from __future__ import annotations

import sys
import time
from pathlib import Path

import pytest

from langtraj.cases import Case, Criteria
from langtraj.suites import EpisodeTask, run_episode
from suites.fakes import FAKE_ENV, TESTS_DIR, FakeEnv, write_scene


def _task(tmp_path: Path, scene: str = "good", planner: str | None = "suites.fakes:GoodPlanner", **kw) -> EpisodeTask:
    behaviour = kw.pop("behaviour", {})
    case_keys = {k: kw.pop(k) for k in list(kw) if k in Case.__dataclass_fields__}
    case = Case(name=f"{scene}-case", scenario=write_scene(tmp_path, scene, **behaviour), **case_keys)
    options = {"planner": planner, "planner_cmd": None, "step_timeout": 5.0, "video": False} | kw
    return EpisodeTask(suite="s", case=case, seed=0, out=tmp_path / "out", env=FAKE_ENV, **options)


def test_a_good_episode_passes_and_records_every_step(tmp_path):
    result = run_episode(_task(tmp_path))
    assert (result.status, result.reasons, result.ego) == ("pass", [], 17)
    assert result.figures["steps"] == 80 and len(result.steps["speed"]) == 80
    assert [c["name"] for c in result.criteria] == ["no_at_fault_collision", "no_offroad"]


def test_the_env_gets_the_case(tmp_path):
    FakeEnv.built.clear()
    run_episode(_task(tmp_path, ego=5, prompts=("@9 follows @ego",), adversary=9, target="ego", index=2))
    assert FakeEnv.built[-1] == {"index": 2, "ego": 5, "prompts": ["@9 follows @ego"], "target": "ego"}


def test_criteria_fail_with_their_reasons(tmp_path):
    result = run_episode(_task(tmp_path, behaviour={"collide_at": 30, "at_fault": True}, criteria=Criteria(min_ttc=1)))
    assert result.status == "fail" and result.reasons == ["at-fault collision with 7 at step 30"]
    assert result.figures["steps"] == 30  # terminate_on_collision ends the episode there
    kept = run_episode(
        _task(
            tmp_path, behaviour={"collide_at": 30}, criteria=Criteria(no_collision=True, terminate_on_collision=False)
        )
    )
    assert kept.figures["steps"] == 80 and kept.reasons == ["collision with 7 at step 30"]


def test_max_steps_cuts_the_episode(tmp_path):
    result = run_episode(_task(tmp_path, max_steps=5))
    assert result.status == "pass" and result.figures["steps"] == 5


@pytest.mark.parametrize(
    ("planner", "reason"),
    [
        ("RaisingPlanner", "planner raised ValueError: boom at step 3"),
        ("NaNPlanner", "planner returned a non-finite action at step 12"),
        ("WrongShapePlanner", "planner returned an action of shape (3,), expected (2,) at step 1"),
    ],
)
def test_a_bad_planner_fails_with_one_line(tmp_path, planner, reason):
    result = run_episode(_task(tmp_path, "bad", f"suites.fakes:{planner}"))
    assert (result.status, result.reasons) == ("fail", [reason])
    if planner == "RaisingPlanner":  # the planner's own traceback is kept for its author
        assert "Traceback" in result.traceback and "ValueError: boom" in result.traceback
    else:
        assert result.traceback is None


def test_a_hanging_planner_is_stopped_by_the_step_limit(tmp_path):
    for planner, step in (("HangingPlanner", 2), ("SwallowingHangPlanner", 1)):
        start = time.perf_counter()
        result = run_episode(_task(tmp_path, "bad", f"suites.fakes:{planner}", step_timeout=1.0))
        assert (result.status, result.reasons) == ("fail", [f"planner timed out after 1 s at step {step}"])
        assert time.perf_counter() - start < 30  # cut short, not waited out (the hang is 60 s): no speed limit


def test_a_hanging_planner_command_is_stopped_by_its_timeout(tmp_path, monkeypatch):
    monkeypatch.setenv("PYTHONPATH", str(TESTS_DIR))
    command = f"{sys.executable} -m langtraj.planners.serve suites.fakes:HangingPlanner"
    good = run_episode(_task(tmp_path, "good", None, planner_cmd=command, step_timeout=2.0))
    assert good.status == "pass", good.reasons
    result = run_episode(_task(tmp_path, "bad", None, planner_cmd=command, step_timeout=1.0))
    assert (result.status, result.reasons) == ("fail", ["planner timed out after 1 s at step 2"])
    assert (tmp_path / "out" / "planner-logs" / "bad-case-seed0.log").is_file()


def test_a_planner_command_that_breaks_fails_the_case(tmp_path):
    result = run_episode(_task(tmp_path, None, planner_cmd=f"{sys.executable} -c 'import sys; sys.exit(3)'"))
    assert result.status == "fail" and result.reasons[0].startswith("planner failed when started: planner")
    assert "exited (code 3)" in result.reasons[0] and "\n" not in result.reasons[0]


def test_duck_typed_planner_with_one_argument_reset_and_trajectories(tmp_path):
    assert run_episode(_task(tmp_path, planner="suites.fakes:OneArgumentPlanner")).status == "pass"


def test_env_errors_are_errors_not_failures(tmp_path):
    broken = run_episode(_task(tmp_path, behaviour={"error_at": 7}))
    assert broken.status == "error" and broken.reasons == ["LangTraj raised RuntimeError: the fake env broke at step 7"]
    assert "Traceback" in broken.traceback and broken.figures["steps"] == 6
    unbuilt = run_episode(_task(tmp_path, behaviour={"error_at": 0}))
    assert unbuilt.status == "error" and "before the episode started" in unbuilt.reasons[0]
    assert "the fake scene cannot be built" in unbuilt.reasons[0]
    assert unbuilt.input_error == ("the fake scene cannot be built", "scenario") and broken.input_error is None


def test_a_failed_episode_gets_a_video(tmp_path):
    result = run_episode(_task(tmp_path, behaviour={"collide_at": 3, "at_fault": True}, video=True))
    assert result.status == "fail" and result.video == "videos/good-case-seed0.mp4", result.video_error
    assert (tmp_path / "out" / result.video).stat().st_size > 0
    passed = run_episode(_task(tmp_path, video=True, max_steps=3))
    assert passed.video is None
