"""The figures of an episode and the criteria's verdicts on them."""

from __future__ import annotations

import math

from langtraj.cases import Criteria
from langtraj.suites.verdict import StepRecord, episode_figures, judge


def _record(n: int = 10, **at) -> StepRecord:
    record = StepRecord()
    for k in range(1, n + 1):
        collision = "collide" in at and k >= at["collide"]
        record.add(
            {
                "collision": collision,
                "collided_with": [7, 9] if collision else [],
                "at_fault": collision and at.get("at_fault", False),
                "offroad": "offroad" in at and k >= at["offroad"],
                "ttc": at.get("ttc", {}).get(k, 5.0),
                "min_distance": 10.0 - k * 0.5,
                "progress": k / n * at.get("progress", 1.0),
                "progress_m": float(k),
                "speed": 10.0,
                "acceleration": at.get("acceleration", {}).get(k, 0.0),
                "yaw_rate": 0.0,
                "red_light": k in at.get("red", ()),
                "wrong_way": k in at.get("wrong", ()),
                "over_speed_limit": at.get("over", {}).get(k, 0.0),
            }
        )
    return record


def _reasons(criteria: Criteria, record: StepRecord) -> dict[str, str | None]:
    return {v.name: v.reason for v in judge(criteria, episode_figures(record)) if not v.passed}


def test_a_clean_episode_passes_every_criterion():
    figures = episode_figures(_record())
    assert figures["steps"] == 10 and figures["first_collision_step"] is None and figures["min_ttc"] == 5.0
    assert figures["final_progress"] == 1.0 and figures["min_distance"] == 5.0 and figures["mean_speed"] == 10.0
    verdicts = judge(Criteria(no_collision=True, min_ttc=1.0, min_progress=0.9), figures)
    assert [v.name for v in verdicts] == [
        "no_at_fault_collision",
        "no_collision",
        "no_offroad",
        "min_ttc",
        "min_progress",
    ]
    assert all(v.passed for v in verdicts)


def test_collisions_at_fault_and_not():
    not_at_fault = _record(collide=4)
    assert _reasons(Criteria(), not_at_fault) == {}  # being hit does not fail by default
    assert _reasons(Criteria(no_collision=True), not_at_fault) == {"no_collision": "collision with 7, 9 at step 4"}
    at_fault = _record(collide=6, at_fault=True)
    figures = episode_figures(at_fault)
    assert (figures["first_at_fault_step"], figures["at_fault_with"]) == (6, [7, 9])
    assert _reasons(Criteria(), at_fault) == {"no_at_fault_collision": "at-fault collision with 7, 9 at step 6"}
    assert _reasons(Criteria(no_at_fault_collision=False), at_fault) == {}


def test_offroad_ttc_and_progress():
    assert _reasons(Criteria(), _record(offroad=8)) == {"no_offroad": "offroad at step 8 (3 steps in all)"}
    assert _reasons(Criteria(no_offroad=False), _record(offroad=8)) == {}
    close = _record(ttc={3: 0.42})
    assert _reasons(Criteria(min_ttc=1.0), close) == {"min_ttc": "min TTC 0.42 s < 1 s at step 3"}
    assert _reasons(Criteria(min_ttc=0.4), close) == {}
    slow = _record(progress=0.3)
    assert _reasons(Criteria(min_progress=0.5), slow) == {"min_progress": "progress 0.30 < 0.5 of the logged ego's"}


def test_unmeasured_figures():
    record = _record(progress=math.nan)  # the logged ego does not move: progress is NaN
    assert record.progress[-1] is None
    assert "not measured" in _reasons(Criteria(min_progress=0.1), record)["min_progress"]
    empty = episode_figures(StepRecord())
    assert empty["steps"] == 0 and empty["min_ttc"] is None and empty["final_progress"] is None
    assert all(v.passed for v in judge(Criteria(min_ttc=1.0), empty))


def test_the_rules_of_the_road_and_comfort():
    rules = Criteria(no_red_light=True, no_wrong_way=True, max_over_speed_limit=1.0, comfortable=True)
    assert _reasons(rules, _record()) == {}
    broken = _record(red=(3,), wrong=(5, 6), over={4: 2.5}, acceleration={7: -6.0})
    assert _reasons(rules, broken) == {
        "no_red_light": "ran a red light at step 3 (1 steps in all)",
        "no_wrong_way": "drove against its lane at step 5 (2 steps in all)",
        "max_over_speed_limit": "2.5 m/s over the speed limit (allowed 1)",
        "comfortable": "uncomfortable: min_acceleration -6 (bound -4.05), max_abs_jerk 60 (bound 4.13)",
    }
    assert _reasons(Criteria(), broken) == {}  # all off by default
    unreported = StepRecord()
    unreported.add({"collision": False, "at_fault": False, "offroad": False, "speed": 10.0})  # an env without rules
    assert "not measured" in _reasons(Criteria(no_red_light=True), unreported)["no_red_light"]
