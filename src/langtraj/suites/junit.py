"""`junit.xml`: a suite run for CI (JUnit XML, as pytest writes it for a parametrized test): one `<testsuite>`
named after the suite, one `<testcase classname="SUITE" name="CASE[seedK]">` per episode with its seconds, so CI
shows which seed failed. A failed episode gets `<failure message="reason; reason">` (with the planner's traceback
when it raised), an errored one `<error>` with LangTraj's traceback, one whose scenario did not happen `<skipped
type="not_happened">` (not a pass: the case tested nothing), one that did not finish (an interrupted run)
`<skipped>`. Every finished episode's `<system-out>` is its status line, then one line per prompt judged by numbers
with the asked and realised values side by side, then its traffic: the other agents' collisions and off-road, and
why the ego's failure follows one (docs/testing.md, 'Scenario suites', 'Judged by numbers' and 'Traffic faults')."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

from langtraj.fileio import atomic_path
from langtraj.interdrive.judging import Measure
from langtraj.suites.episode import EpisodeResult
from langtraj.suites.results import SuiteResults
from langtraj.suites.traffic import traffic_text

JUNIT_FILE = "junit.xml"


def junit_name(case: str, seed: int) -> str:
    """The JUnit name of an episode: `CASE[seedK]`, as pytest names a parametrized test."""
    return f"{case}[seed{seed}]"


def _line(result: EpisodeResult) -> str:
    reasons = f": {' / '.join(result.reasons)}" if result.reasons else ""
    return f"{result.status}{reasons}" + (f" (video: {result.video})" if result.video else "")


def measure_lines(result: EpisodeResult) -> list[str]:
    """One line per prompt of `result` judged by numbers: `PROMPT: gap 15 m asked, 2.5 m done (+-3 m) MISSED; ...`."""
    lines = []
    for prompt in result.prompts:
        measures = [Measure.from_json(m) for m in prompt.get("measures", [])]
        if measures:
            said = "; ".join(m.describe() + (" MISSED" if m.ok is False else "") for m in measures)
            lines.append(f"{prompt['text']}: {said}")
    return lines


def traffic_lines(result: EpisodeResult) -> list[str]:
    """`traffic: ...` (the other agents' collisions and off-road) and `traffic fault: ...` (why the ego's failure
    follows one), where recorded."""
    lines = [] if result.traffic is None else [f"traffic: {traffic_text(result.traffic)}"]
    return lines + ([f"traffic fault: {result.traffic_fault_reason}"] if result.traffic_fault else [])


def junit_tree(results: SuiteResults) -> ET.ElementTree:
    """The JUnit XML document of `results`."""
    counts = {"tests": 0, "failures": 0, "errors": 0, "skipped": 0}
    total = 0.0
    suite = ET.Element("testsuite", name=results.suite.name, timestamp=str(results.header["started"]))
    for case in results.suite.cases:
        for seed in case.seeds:
            result = results.episodes.get((case.name, seed))
            seconds = result.seconds if result else 0.0
            total += seconds
            counts["tests"] += 1
            name = junit_name(str(case.name), seed)
            element = ET.SubElement(suite, "testcase", classname=results.suite.name, name=name, time=f"{seconds:.3f}")
            if result is None:
                counts["skipped"] += 1
                ET.SubElement(element, "skipped", message="not run to its end (the run was interrupted)")
                continue
            if result.status == "not_happened":
                counts["skipped"] += 1
                message = "; ".join(result.reasons)
                ET.SubElement(element, "skipped", message=message, type="not_happened").text = _line(result)
            elif result.status in ("fail", "error"):
                counts["failures" if result.status == "fail" else "errors"] += 1
                message = "; ".join(result.reasons) or result.status
                child = ET.SubElement(element, "failure" if result.status == "fail" else "error", message=message)
                child.set("type", result.status)
                child.text = "\n".join(t for t in (_line(result), result.traceback) if t)
            out = [_line(result), *measure_lines(result), *traffic_lines(result)]
            ET.SubElement(element, "system-out").text = "\n".join(out)
    for key, value in counts.items():
        suite.set(key, str(value))
    suite.set("time", f"{total:.3f}")
    root = ET.Element("testsuites", {k: suite.get(k) or "0" for k in ("tests", "failures", "errors", "time")})
    root.set("name", results.suite.name)
    root.append(suite)
    ET.indent(root)
    return ET.ElementTree(root)


def write_junit(results: SuiteResults, out: Path) -> Path:
    path = Path(out) / JUNIT_FILE
    with atomic_path(path) as tmp:
        junit_tree(results).write(tmp, encoding="utf-8", xml_declaration=True)
    return path
