"""Whether a suite's cases tell a careless planner from a careful one: the suite run under the three planners to
calibrate against (`CALIBRATION_PLANNERS`: the IDM, the cautious one that brakes for anything in its path and the
careless constant-velocity one), and per case whether its scenario happened under each, the cautious planner passed
and the careless one failed through the prompted agent (docs/testing.md, 'Planners to calibrate against').

`langtraj test SUITE --calibrate --out DIR` writes each planner's reports to `DIR/<planner>/` and this comparison to
`DIR/calibration.md` and `DIR/calibration.json`.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from langtraj.cases import Case
from langtraj.fileio import atomic_path
from langtraj.interdrive.behaviour import KINDS
from langtraj.interdrive.behaviours import kind
from langtraj.suites.episode import EpisodeResult
from langtraj.suites.results import SuiteResults

CALIBRATION_PLANNERS = ("idm", "cautious", "constant_velocity")
"""The planners a scenario is checked against: the reference, the careful end and the careless end."""
CAREFUL, CARELESS = "cautious", "constant_velocity"
CALIBRATION_FILE = "calibration"
"""`calibration.md` and `calibration.json` in the output folder."""


@dataclass(frozen=True)
class PlannerTally:
    """One case's episodes under one planner: how many, in how many the scenario happened, passed, failed, failed by a
    collision with an agent a prompt names, and were cut short (failed before the scenario happened: a planner that
    hits a bystander at 0.6 s never met the cut-in; `happened`)."""

    planner: str
    episodes: int
    happened: int
    passed: int
    failed: int
    failed_through_prompted: int
    cut_short: int = 0

    @classmethod
    def of(cls, planner: str, results: Sequence[EpisodeResult], staged: set[int]) -> PlannerTally:
        """The tally of `results`, failing "through the prompted agent" by any collision with one of `staged`
        (`verdict.contacts`: every contact, not only the first)."""
        happened = [r for r in results if happened_in(r, staged)]
        failed = [r for r in happened if r.status == "fail"]
        return cls(
            planner,
            len(results),
            len(happened),
            sum(r.status == "pass" for r in happened),
            len(failed),
            sum(bool(staged & _hit(r)) for r in failed),
            sum(r.status == "fail" for r in results) - len(failed),
        )

    def to_json(self) -> dict[str, Any]:
        return dict(vars(self))


def _hit(result: EpisodeResult) -> set[int]:
    """The agents the ego touched in the episode (every contact, `verdict.contacts`)."""
    return {c["with"] for c in result.figures.get("collisions") or ()}


def happened_in(result: EpisodeResult, staged: set[int]) -> bool:
    """Whether the case's scenario happened in the episode: it passed (every prompt followed), or it failed by a
    collision with an agent of `staged` (the adversary got in the ego's way) or with every prompt followed up to the
    failure (`PromptVerdict.followed` not False, judged on the played steps). A failure before the scenario (a
    contact with a bystander at 0.6 s, the cut-in not begun) did not test it: cut short, not happened."""
    if result.status == "pass":
        return True
    if result.status != "fail":
        return False
    return bool(staged & _hit(result)) or not any(p.get("followed") is False for p in result.prompts)


def _staged(case: Case, results: Sequence[EpisodeResult]) -> set[int]:
    """The agents a case puts in the ego's path: those a prompt asks a behaviour that ends in the other's path
    (`BehaviourKind.in_path`: a cut-in, a braking lead, ...) toward the ego, and the case's adversary driven at the
    ego by collision guidance."""
    staged = {int(case.adversary)} if case.adversary is not None and case.target in ("ego", None) else set()
    for result in results:
        for prompt in result.prompts:
            behaviour, agent = prompt.get("behaviour"), prompt.get("agent")
            toward_ego = prompt.get("other") in (None, result.ego)
            if behaviour in KINDS.names() and kind(behaviour).in_path and agent is not None and toward_ego:
                staged.add(int(agent))
    return staged


@dataclass(frozen=True)
class CaseCalibration:
    """One case under the three planners: each planner's tally, whether the case separates the careful planner from
    the careless one (`separates`: None for a case that puts no agent in the ego's path), and one line saying why
    not."""

    case: str
    tallies: tuple[PlannerTally, ...]
    separates: bool | None
    why: str

    def to_json(self) -> dict[str, Any]:
        return {
            "case": self.case,
            "separates": self.separates,
            "why": self.why,
            "planners": {t.planner: t.to_json() for t in self.tallies},
        }


def calibrate(runs: Mapping[str, SuiteResults]) -> list[CaseCalibration]:
    """Each case of the suite the `runs` (planner name -> its results) ran: it separates when its scenario happened in
    every episode under every planner, the cautious planner passed every one and the careless one failed every one
    through the agent the case puts in the ego's path (`_staged`)."""
    first = next(iter(runs.values()))
    out = []
    for case in first.suite.cases:
        staged = _staged(case, [e for r in runs.values() for e in r.of_case(case.name)])
        tallies = tuple(PlannerTally.of(p, r.of_case(case.name), staged) for p, r in runs.items())
        by = {t.planner: t for t in tallies}
        if not staged:
            why = "puts no agent in the ego's path (no adversary, no cut-in, braking lead, ...): nothing to separate"
            out.append(CaseCalibration(case.name, tallies, None, why))
            continue
        why = [
            f"did not happen in {t.episodes - t.happened} of {t.episodes} under {t.planner}"
            + (f" ({t.cut_short} cut short by a failure first)" if t.cut_short else "")
            for t in tallies
            if t.happened < t.episodes
        ]
        careful, careless = by.get(CAREFUL), by.get(CARELESS)
        if careful is not None and careful.passed < careful.happened:
            why.append(f"the cautious planner failed {careful.happened - careful.passed} of {careful.happened}")
        if careless is not None and careless.failed_through_prompted < careless.happened:
            passed = careless.happened - careless.failed_through_prompted
            why.append(
                f"the careless planner did not fail through the prompted agent in {passed} of {careless.happened}"
            )
        out.append(CaseCalibration(case.name, tallies, not why, "; ".join(why) or "separates"))
    return out


def write_calibration(out: Path, rows: Sequence[CaseCalibration]) -> None:
    """`calibration.json` and `calibration.md` in `out`, each written atomically."""
    data = {"planners": list(CALIBRATION_PLANNERS), "cases": [r.to_json() for r in rows], "summary": summary(rows)}
    with atomic_path(Path(out) / f"{CALIBRATION_FILE}.json") as tmp:
        tmp.write_text(json.dumps(data, indent=2) + "\n")
    with atomic_path(Path(out) / f"{CALIBRATION_FILE}.md") as tmp:
        tmp.write_text(markdown(rows))


def summary(rows: Sequence[CaseCalibration]) -> str:
    staged = [r for r in rows if r.separates is not None]
    return (
        f"{sum(bool(r.separates) for r in staged)} of {len(staged)} cases that stage a scenario separate the planners"
    )


def markdown(rows: Sequence[CaseCalibration]) -> str:
    """The comparison as a table: per case and planner, happened / passed / failed through the prompted agent."""
    planners = [t.planner for t in rows[0].tallies] if rows else list(CALIBRATION_PLANNERS)
    head = "| case | " + " | ".join(planners) + " | separates |"
    lines = [
        "# Calibration: does each case tell a careless planner from a careful one?",
        "",
        "Per planner: episodes where the scenario happened / passed / failed through the prompted agent, of all. An",
        "episode that failed before its scenario happened (a bystander hit first) is cut short: not happened.",
        "",
        head,
        "| --- " * (len(planners) + 2) + "|",
    ]
    for row in rows:
        cells = [f"{t.happened} / {t.passed} / {t.failed_through_prompted} of {t.episodes}" for t in row.tallies]
        verdict = "n/a" if row.separates is None else ("yes" if row.separates else f"no: {row.why}")
        lines.append(f"| {row.case} | " + " | ".join(cells) + f" | {verdict} |")
    return "\n".join([*lines, "", summary(rows), ""])
