"""`junit.xml`: a suite run for CI (JUnit XML, as pytest writes it): one `<testsuite>` named after the suite, one
`<testcase classname="SUITE" name="CASE">` per case with its time (the sum of its episodes' seconds). A case
fails when any of its seeds fails: `<failure message="seed 0: reason; seed 2: reason">`; a case none of whose
seeds failed but some errored gets `<error>` instead (docs/testing.md, 'Scenario suites')."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

from langtraj.fileio import atomic_path
from langtraj.suites.results import SuiteResults

JUNIT_FILE = "junit.xml"


def _message(results: list, status: str) -> str:
    return "; ".join(f"seed {r.seed}: {' / '.join(r.reasons) or status}" for r in results if r.status == status)


def junit_tree(results: SuiteResults) -> ET.ElementTree:
    """The JUnit XML document of `results`."""
    statuses = results.case_statuses()
    counts = {"tests": 0, "failures": 0, "errors": 0, "skipped": 0}
    total = 0.0
    suite = ET.Element("testsuite", name=results.suite.name, timestamp=str(results.header["started"]))
    for case in results.suite.cases:
        episodes = results.of_case(case.name)
        seconds = sum(r.seconds for r in episodes)
        total += seconds
        counts["tests"] += 1
        element = ET.SubElement(suite, "testcase", classname=results.suite.name, name=case.name, time=f"{seconds:.3f}")
        status = statuses[case.name]
        lines = [
            f"seed {r.seed}: {r.status}"
            + (f": {' / '.join(r.reasons)}" if r.reasons else "")
            + (f" (video: {r.video})" if r.video else "")
            for r in episodes
        ]
        if status == "fail":
            counts["failures"] += 1
            child = ET.SubElement(element, "failure", message=_message(episodes, "fail"), type="fail")
            child.text = "\n".join(lines)
        elif status == "error":
            counts["errors"] += 1
            child = ET.SubElement(element, "error", message=_message(episodes, "error"), type="error")
            child.text = "\n".join(lines + [r.traceback or "" for r in episodes if r.status == "error"])
        elif status == "pending":
            counts["skipped"] += 1
            ET.SubElement(element, "skipped", message="not run to its end (the run was interrupted)")
        if status != "pending":
            ET.SubElement(element, "system-out").text = "\n".join(lines)
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
