"""Traffic faults: the other agents' collisions and off-road recorded per episode (who, when, with whom, the ego part
of it or not), the ego's failure flagged when it follows one, and the lines of results.json, report.md and JUnit."""

from __future__ import annotations

import json
import sys
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from langtraj.cases import Case, Criteria
from langtraj.suites import EpisodeTask, RunOptions, load_suite, run_episode, run_suite
from langtraj.suites.traffic import EgoFailure, Traffic, TrafficEvent, follows_traffic_fault
from suites.conftest import write_suite
from suites.fakes import FAKE_ENV, TESTS_DIR, write_scene

EGO = 17  # the fake's ego: in the toy scene, at x = -12 + 5 t, y = 3.5


def crash(step: int, ahead_m: float) -> list[dict[str, Any]]:
    """27 and 37 placed on top of each other `ahead_m` in front of the ego from `step` on."""
    return [
        {"move": 27, "at": step, "onto": EGO, "dx": ahead_m},
        {"move": 37, "at": step, "onto": EGO, "dx": ahead_m + 0.5},
    ]


def _run(tmp_path: Path, criteria: Criteria | None = None, adversary: int | None = None, **behaviour: Any):
    scene = write_scene(tmp_path, "scene", **behaviour)
    case = Case(name="c", scenario=scene, criteria=criteria or Criteria(), adversary=adversary)
    task = EpisodeTask(
        suite="s", case=case, seed=0, planner="suites.fakes:GoodPlanner", planner_cmd=None, step_timeout=5.0,
        out=tmp_path / "out", video=False, env=FAKE_ENV,
    )  # fmt: skip
    return run_episode(task)


def test_traffic_faults_are_recorded_with_who_when_and_with_whom(tmp_path):
    result = _run(tmp_path, traffic=[*crash(20, 40.0), {"move": 7, "at": 30, "dy": -4.0}])
    assert result.status == "pass" and not result.traffic_fault and result.traffic_fault_reason is None
    traffic = result.traffic
    counts = (traffic["collisions"], traffic["offroad"], traffic["faults"], traffic["offroad_measured"])
    assert counts == (1, 1, 2, True)
    collision, offroad = traffic["events"]
    assert collision == {
        "kind": "collision", "agent": 27, "with": 37, "step": 20, "time": 2.0, "cause": "other", "ego": False,
        "ego_distance_m": 40.0, "fault": True,
    }  # fmt: skip
    assert (offroad["kind"], offroad["agent"], offroad["with"], offroad["step"], offroad["time"]) == (
        "offroad",
        7,
        None,
        30,
        3.0,
    )
    assert offroad["fault"] and not offroad["ego"]
    assert json.loads(json.dumps(result.to_json()))["traffic"] == traffic


def test_a_quiet_episode_has_no_traffic_faults(tmp_path):
    result = _run(tmp_path, traffic=[])
    assert result.traffic == {"collisions": 0, "offroad": 0, "faults": 0, "offroad_measured": True, "events": []}


def test_the_egos_own_collisions_are_not_traffic_faults(tmp_path):
    """Overlapping the ego in the played scene is the ego's collision (the step info's), not traffic."""
    touching = _run(tmp_path, traffic=[{"move": 27, "at": 20, "onto": EGO}])
    assert touching.traffic["events"] == []
    # 37 touched the ego at step 10, then 27 at step 20: the ego was part of it, listed but not counted or flagged
    on = Criteria(terminate_on_collision=False)
    after = _run(tmp_path, on, traffic=crash(20, 40.0), collide_at=10, collided_with=[37], at_fault=True)
    (event,) = after.traffic["events"]
    assert (event["agent"], event["with"], event["ego"], event["fault"]) == (27, 37, True, False)
    assert after.traffic["faults"] == 0 and after.status == "fail" and not after.traffic_fault


def test_an_ego_collision_with_an_agent_that_had_crashed_before_is_flagged(tmp_path):
    result = _run(tmp_path, traffic=crash(20, 40.0), collide_at=30, collided_with=[37], at_fault=True)
    assert result.status == "fail" and result.reasons == ["at-fault collision with 37 at step 30"]
    assert result.traffic_fault
    assert result.traffic_fault_reason == (
        "at-fault collision with 37 at step 30 follows @37's traffic fault: collision @27-@37 at 2.0 s"
    )
    other = _run(tmp_path, traffic=crash(20, 40.0), collide_at=30, collided_with=[7], at_fault=True)
    assert other.status == "fail" and not other.traffic_fault  # another agent, 40 m from the crash


def test_an_ego_failure_soon_after_a_traffic_fault_near_it_is_flagged(tmp_path):
    near = _run(tmp_path, traffic=crash(20, 10.0), offroad_at=40)
    assert near.status == "fail" and near.traffic_fault
    assert near.traffic_fault_reason == (
        "offroad at step 40 (41 steps in all) follows a traffic fault 10 m from the ego, 2.0 s before: "
        "collision @27-@37 at 2.0 s"
    )
    later = _run(tmp_path, traffic=crash(20, 10.0), offroad_at=60)  # 4 s after: more than FOLLOW_S
    far = _run(tmp_path, traffic=crash(20, 40.0), offroad_at=40)  # 40 m away: more than NEAR_M
    before = _run(tmp_path, traffic=crash(20, 10.0), offroad_at=15)  # before the fault
    assert [r.status for r in (later, far, before)] == ["fail"] * 3
    assert not any(r.traffic_fault for r in (later, far, before))


def test_a_collision_with_the_staged_agent_follows_only_its_own_fault(tmp_path):
    """The adversary (or a prompted agent) hitting the ego is the case's own failure, whatever crashed near by."""
    hit = {"collide_at": 30, "collided_with": [47], "at_fault": True}
    bystander = _run(tmp_path, traffic=crash(20, 10.0), **hit)
    staged = _run(tmp_path, adversary=47, traffic=crash(20, 10.0), **hit)
    assert bystander.traffic_fault and "follows a traffic fault 10 m from the ego" in bystander.traffic_fault_reason
    assert staged.status == "fail" and not staged.traffic_fault
    crashed = _run(tmp_path, adversary=37, traffic=crash(20, 10.0), collide_at=30, collided_with=[37], at_fault=True)
    assert crashed.traffic_fault and "follows @37's traffic fault" in crashed.traffic_fault_reason


def test_a_criterion_without_a_step_follows_a_fault_near_the_ego_at_any_time(tmp_path):
    slow = Criteria(min_progress=0.5)
    near = _run(tmp_path, slow, traffic=crash(20, 10.0), progress=0.2)
    far = _run(tmp_path, slow, traffic=crash(20, 40.0), progress=0.2)
    assert near.status == far.status == "fail"
    assert near.traffic_fault
    assert near.traffic_fault_reason.startswith("progress 0.20 < 0.5 of the logged ego's follows a traffic fault 10 m")
    assert not far.traffic_fault


def test_the_rule_on_events():
    fault = TrafficEvent("offroad", 40, None, 50, "drift", False, 8.0)
    listed = TrafficEvent("collision", 3, 4, 50, "log_overlap", False, 1.0)  # touching in the log: not a fault
    traffic = Traffic((fault, listed), True)
    assert [e.fault for e in traffic.events] == [True, False]
    assert follows_traffic_fault(traffic, [EgoFailure("min TTC", 70, ())]) is not None  # 2 s after, 8 m away
    assert follows_traffic_fault(traffic, [EgoFailure("collision with 3 at step 90", 90, (3,))]) is None  # 4 s after
    assert follows_traffic_fault(traffic, [EgoFailure("collision with 40 at step 90", 90, (40,))]) == (
        "collision with 40 at step 90 follows @40's traffic fault: offroad @40 at 5.0 s"
    )


def test_traffic_on_every_report(tmp_path):
    write_scene(tmp_path, "busy", traffic=[*crash(20, 40.0), {"move": 7, "at": 30, "dy": -4.0}])
    write_scene(tmp_path, "chain", traffic=crash(20, 40.0), collide_at=30, collided_with=[37], at_fault=True)
    write_scene(tmp_path, "quiet", traffic=[])
    cases = [{"name": n, "scenario": f"{n}.json"} for n in ("busy", "chain", "quiet")]
    options = RunOptions(out=tmp_path / "out", planner="suites.fakes:GoodPlanner", env=FAKE_ENV, video=False)
    run_suite(load_suite(write_suite(tmp_path, cases)), options)
    saved = json.loads((options.out / "results.json").read_text())
    summary = {k: v for k, v in saved["summary"].items() if k.startswith("traffic")}
    assert summary == {
        "traffic_collisions": 2, "traffic_offroad": 1, "traffic_episodes": 2, "traffic_flagged": 1,
        "traffic_flagged_failed": 1,
    }  # fmt: skip
    busy, chain, _ = saved["episodes"]
    assert chain["traffic_fault"] and not busy["traffic_fault"] and chain["status"] == "fail"
    assert chain["traffic_fault_reason"].startswith("at-fault collision with 37 at step 30 follows @37's")
    report = (options.out / "report.md").read_text()
    assert "traffic faults in 2 episodes (2 collisions among other agents, 1 off-road), 1 ego failures" in report
    assert "Traffic, seed 0: 1 collision among other agents (@27-@37 at 2.0 s), 1 off-road (@7 at 3.0 s)  " in report
    assert "Traffic, seed 0: no collision or off-road among other agents  " in report
    assert "**Traffic fault, seed 0** (status FAIL kept): at-fault collision with 37 at step 30 follows" in report
    root = ET.parse(options.out / "junit.xml").getroot()
    out = {c.get("name"): c.find("system-out").text for c in root.iter("testcase")}
    assert "traffic: 1 collision among other agents (@27-@37 at 2.0 s), 1 off-road (@7 at 3.0 s)" in out["busy[seed0]"]
    assert "traffic fault: at-fault collision with 37 at step 30 follows @37's traffic fault" in out["chain[seed0]"]
    assert "traffic fault" not in out["busy[seed0]"]


def replay_env(**kwargs: Any) -> Any:
    """The real environment, its other agents replaying their log (`policy="log_replay"`): cheap, no model."""
    from langtraj.env import LangTrajEnv

    return LangTrajEnv(policy="log_replay", **kwargs)


def _bystanders_crash():
    """The two-lane road: the ego (1) at 10 m/s in the right lane; in the left lane 2 (15 m/s) runs into 3 (5 m/s,
    25 m ahead) after about 2 s; 4 drifts off the road's left edge from 3 s on."""
    sys.path.insert(0, str(TESTS_DIR))
    from dataclasses import replace

    from scenario_builders import two_lane_road

    scene = two_lane_road([(0.0, 0.0, 10.0), (-30.0, 3.5, 15.0), (-5.0, 3.5, 5.0), (60.0, 3.5, 10.0)])
    states = scene.agents.states.copy()
    drift = np.clip((np.arange(scene.num_steps) - 40) * 0.3, 0.0, None)
    states[3, :, 1] += drift.astype(np.float32)
    return replace(scene, agents=replace(scene.agents, states=states))


def test_the_real_env_records_bystanders_crashing(tmp_path):
    pytest.importorskip("torch")
    case = Case(name="replay", scenario=_bystanders_crash(), ego=1)
    task = EpisodeTask(
        suite="s", case=case, seed=0, planner="suites.fakes:GoodPlanner", planner_cmd=None, step_timeout=30.0,
        out=tmp_path / "out", video=False, env="suites.test_traffic:replay_env",
    )  # fmt: skip
    result = run_episode(task)
    assert result.status == "pass", result.reasons
    events = [(e["kind"], e["agent"], e["with"], e["fault"], e["ego"]) for e in result.traffic["events"]]
    assert events == [("collision", 2, 3, True, False), ("offroad", 4, None, True, False)]
    collision, offroad = result.traffic["events"]
    assert 19 <= collision["step"] <= 22 and 30 <= offroad["step"] <= 45
    assert not result.traffic_fault  # the ego kept every criterion and touched nobody
