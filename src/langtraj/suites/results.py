"""The results of a suite run as they arrive: `results.json`, rewritten atomically after every finished episode,
so that a run that crashes or is interrupted leaves every finished episode on disk (docs/testing.md, 'Scenario
suites').

results.json:
    suite, suite_file: the suite's name and file. planner / planner_cmd: what drove the ego (one is null).
    step_timeout: the per-call limit (s). started, finished: ISO 8601 times (finished null while running).
    complete: whether every episode has finished. summary: `summary()`. cases: each case as
    `langtraj.cases.case_json` writes it (every key of a suite's case), with its `status` (`case_status`) and its
    `measures` (`case_measures`: per prompt and number judged, the asked value beside each seed's realised one).
    episodes: each finished episode's `EpisodeResult.to_json()`, in suite order (case, then seed); each of its
    `prompts` carries that seed's `measures` (docs/testing.md, 'Judged by numbers'), its `traffic` the other
    agents' collisions and off-road, `traffic_fault` and `traffic_fault_reason` whether the ego's failure follows
    one (docs/testing.md, 'Traffic faults').
"""

from __future__ import annotations

import json
import time
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from langtraj.cases import case_json
from langtraj.fileio import atomic_path
from langtraj.suites.config import Suite
from langtraj.suites.episode import EpisodeResult

RESULTS_FILE = "results.json"


def case_status(results: list[EpisodeResult], expected: int) -> str:
    """A case's status from its episodes: "fail" when any failed, else "error" when any errored, else
    "not_happened" when the scenario did not happen in some, else "pass" once all `expected` finished ("pending"
    before)."""
    statuses = {r.status for r in results}
    for status in ("fail", "error", "not_happened"):
        if status in statuses:
            return status
    return "pass" if len(results) >= expected else "pending"


def case_measures(episodes: list[EpisodeResult]) -> list[dict[str, Any]]:
    """The numbers of a case's prompts judged by numbers, asked beside realised per seed: one row per clause and
    measure (in the order the first episode holding it gives), `{prompt, reading, measure, unit, asked, tolerance,
    seeds: [{seed, realised, ok, followed}]}`; the asked value and tolerance are the first seed's (every seed reads the
    same text)."""
    rows: dict[tuple[int, str], dict[str, Any]] = {}
    for result in episodes:
        for k, prompt in enumerate(result.prompts):
            for m in prompt.get("measures", []):
                row = rows.setdefault(
                    (k, m["name"]),
                    {
                        "prompt": prompt["text"],
                        "reading": prompt["reading"],
                        "measure": m["name"],
                        "unit": m["unit"],
                        "asked": m["asked"],
                        "tolerance": m["tolerance"],
                        "seeds": [],
                    },
                )
                seed = {"seed": result.seed, "realised": m["realised"], "ok": m["ok"], "followed": prompt["followed"]}
                row["seeds"].append(seed)
    return list(rows.values())


def _now() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds")


class SuiteResults:
    """The finished episodes of a run of `suite`, kept in suite order and written to `out/results.json`."""

    def __init__(self, suite: Suite, out: Path, *, planner: str | None, planner_cmd: str | None, step_timeout: float):
        self.suite = suite
        self.path = Path(out) / RESULTS_FILE
        self.header = {
            "suite": suite.name,
            "suite_file": str(suite.path),
            "planner": planner,
            "planner_cmd": planner_cmd,
            "step_timeout": step_timeout,
            "started": _now(),
            "finished": None,
        }
        self.episodes: dict[tuple[str, int], EpisodeResult] = {}
        self._clock = time.perf_counter()
        self.seconds = 0.0

    def add(self, result: EpisodeResult) -> None:
        self.episodes[(result.case, result.seed)] = result

    def of_case(self, name: str) -> list[EpisodeResult]:
        """The finished episodes of case `name`, by seed order of the case."""
        case = next(c for c in self.suite.cases if c.name == name)
        return [self.episodes[(name, s)] for s in case.seeds if (name, s) in self.episodes]

    def ordered(self) -> list[EpisodeResult]:
        return [r for case in self.suite.cases for r in self.of_case(case.name)]

    @property
    def complete(self) -> bool:
        return len(self.episodes) == self.suite.episodes

    @property
    def passed(self) -> bool:
        """Every episode finished and every case passed."""
        return self.complete and all(s == "pass" for s in self.case_statuses().values())

    def case_statuses(self) -> dict[str, str]:
        return {c.name: case_status(self.of_case(c.name), len(c.seeds)) for c in self.suite.cases}

    def summary(self) -> dict[str, Any]:
        """Counts: `episodes` (in the suite), `finished`, `passed`, `failed`, `errors`, `not_happened`; `cases`,
        `cases_passed`, `cases_failed`, `cases_errors`, `cases_not_happened`; the traffic faults (`suites.traffic`):
        `traffic_collisions` and `traffic_offroad` among the other agents, `traffic_episodes` (episodes with one),
        `traffic_flagged` (episodes whose ego failure follows one) and `traffic_flagged_failed` (those that failed);
        and `seconds` of wall time so far."""
        statuses = [r.status for r in self.episodes.values()]
        traffic = [r.traffic for r in self.episodes.values() if r.traffic is not None]
        flagged = [r.status for r in self.episodes.values() if r.traffic_fault]
        cases = list(self.case_statuses().values())
        return {
            "episodes": self.suite.episodes,
            "finished": len(statuses),
            "passed": statuses.count("pass"),
            "failed": statuses.count("fail"),
            "errors": statuses.count("error"),
            "not_happened": statuses.count("not_happened"),
            "cases": len(cases),
            "cases_passed": cases.count("pass"),
            "cases_failed": cases.count("fail"),
            "cases_errors": cases.count("error"),
            "cases_not_happened": cases.count("not_happened"),
            "traffic_collisions": sum(t["collisions"] for t in traffic),
            "traffic_offroad": sum(t["offroad"] for t in traffic),
            "traffic_episodes": sum(1 for t in traffic if t["faults"]),
            "traffic_flagged": len(flagged),
            "traffic_flagged_failed": flagged.count("fail"),
            "seconds": round(self.seconds, 2),
        }

    def to_json(self) -> dict[str, Any]:
        statuses = self.case_statuses()
        cases = [
            {**case_json(c), "status": statuses[c.name], "measures": case_measures(self.of_case(c.name))}
            for c in self.suite.cases
        ]
        return {
            **self.header,
            "complete": self.complete,
            "summary": self.summary(),
            "cases": cases,
            "episodes": [r.to_json() for r in self.ordered()],
        }

    def write(self, *, finished: bool = False) -> None:
        """Rewrite results.json atomically (`finished`: stamp the end time)."""
        self.seconds = time.perf_counter() - self._clock
        if finished:
            self.header["finished"] = _now()
        with atomic_path(self.path) as tmp:
            tmp.write_text(json.dumps(self.to_json(), indent=1))
