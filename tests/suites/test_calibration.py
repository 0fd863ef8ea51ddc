"""The calibration of a suite against the three planners: per case, whether its scenario happened under each, the
cautious planner passed and the careless one failed through the prompted agent (`suites.calibration`)."""

from __future__ import annotations

import json

from langtraj.suites import load_suite
from langtraj.suites.calibration import CALIBRATION_PLANNERS, calibrate, write_calibration
from langtraj.suites.episode import EpisodeResult
from langtraj.suites.results import SuiteResults
from suites.conftest import write_suite
from suites.fakes import write_scene

PROMPT = [{"agent": 7, "other": 1, "behaviour": "cut_in", "followed": True}]


def _episode(case: str, seed: int, status: str, hit: tuple[int, ...] = ()) -> EpisodeResult:
    followed = status != "fail" or bool(hit)  # a failure with no contact but the bystander's: before the cut-in
    prompts = [] if case == "drive" else [PROMPT[0] | {"followed": followed and status != "not_happened"}]
    contacts = [{"step": 10, "with": 3}] + [{"step": 20 + k, "with": a} for k, a in enumerate(hit)]  # @3: a bystander
    return EpisodeResult(case, seed, status, prompts=prompts, ego=1, figures={"collisions": contacts})


def _runs(tmp_path, outcomes: dict[str, dict[str, list[tuple[str, tuple[int, ...]]]]]):
    write_scene(tmp_path, "good")
    cases = [{"name": n, "scenario": "good.json", "seeds": 2} for n in ("cut-in", "cut-in-2", "drive")]
    suite = load_suite(write_suite(tmp_path, cases))
    runs = {}
    for planner in CALIBRATION_PLANNERS:
        results = SuiteResults(suite, tmp_path / planner, planner=planner, planner_cmd=None, step_timeout=10.0)
        for case in suite.cases:
            for seed, (status, hit) in enumerate(outcomes[planner].get(case.name, [("pass", ())] * 2)):
                results.add(_episode(case.name, seed, status, hit))
        runs[planner] = results
    return runs


def test_a_case_separates_when_it_happens_the_careful_pass_and_the_careless_hit_the_prompted_agent(tmp_path):
    crash = ("fail", (7,))
    runs = _runs(
        tmp_path,
        {
            "idm": {"cut-in-2": [("not_happened", ()), ("pass", ())]},
            "cautious": {"cut-in-2": [("pass", ()), ("fail", ())]},  # seed 1: bystander @3 hit before the cut-in
            "constant_velocity": {"cut-in": [crash, crash], "cut-in-2": [crash, ("fail", (9,))]},
        },
    )
    rows = {r.case: r for r in calibrate(runs)}
    assert rows["cut-in"].separates is True and rows["cut-in"].why == "separates"
    assert rows["cut-in-2"].separates is False
    assert rows["cut-in-2"].why == (
        "did not happen in 1 of 2 under idm; did not happen in 1 of 2 under cautious (1 cut short by a failure first);"
        " the careless planner did not fail through the prompted agent in 1 of 2"
    )
    careful = {t.planner: t for t in rows["cut-in-2"].tallies}["cautious"]
    assert (careful.happened, careful.passed, careful.failed, careful.cut_short) == (1, 1, 0, 1)
    assert rows["drive"].separates is None  # no prompt: nothing to separate
    careless = {t.planner: t for t in rows["cut-in-2"].tallies}["constant_velocity"]
    assert (careless.happened, careless.failed, careless.failed_through_prompted) == (2, 2, 1)

    write_calibration(tmp_path, list(rows.values()))
    data = json.loads((tmp_path / "calibration.json").read_text())
    assert data["summary"] == "1 of 2 cases that stage a scenario separate the planners"
    table = (tmp_path / "calibration.md").read_text()
    assert "| cut-in | 2 / 2 / 0 of 2 | 2 / 2 / 0 of 2 | 2 / 0 / 2 of 2 | yes |" in table
