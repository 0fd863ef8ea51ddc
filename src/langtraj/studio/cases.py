"""Keeping a job as a test-suite case: the job's `Case` (scene file, index and window, prompts, collision pair, seed
and checkpoint), named and with optional criteria, appended to a suite YAML under the studio's suites folder
(created with its `name:` when missing). The new file is checked by `suites.config.load_suite` before it replaces
the old one, so a bad case leaves the suite as it was (docs/studio.md, 'POST /api/jobs/{id}/case'; docs/testing.md,
'Scenario suites')."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from langtraj.cases import NAME, Case, case_json, read_case
from langtraj.errors import InputError
from langtraj.fileio import atomic_path
from langtraj.studio.jobs import Job
from langtraj.suites.config import load_suite


class DuplicateCase(InputError):
    """The suite already holds a case of that name (409)."""


def suite_path(suites: Path, suite: str) -> Path:
    if not NAME.fullmatch(suite) or len(suite) > 100:  # a file under the suites folder: no folders, no hidden files
        raise InputError(f"expected a name of letters, digits, '.', '_' and '-', got {suite!r}", where="suite")
    name = suite if suite.endswith(".yaml") else f"{suite}.yaml"
    return Path(suites) / name


def case_of(job: Job, name: str, criteria: dict[str, Any] | None) -> Case:
    """The job's case (its seeds the watched episodes'), named `name`, with `criteria` (keys of
    `langtraj.cases.Criteria`) over the job's; the env chooses the ego, as it did for the job. A job that simulated
    every agent, the ego too, is refused: no planner run of the case would replay it."""
    if job.spec.planner is None:
        raise InputError(
            "this job simulated every agent, the ego too; a case replays what a planner drove: run the job with a "
            "planner to keep it",
            where="job",
        )
    return read_case({"name": name, "criteria": criteria or {}}, defaults=job.spec.case)  # criteria key by key


def save_case(suites: Path, suite: str, case: Case) -> Path:
    """Append `case` (as `case_json` writes it, compactly) to the suite file `suite` under `suites`; returns the
    file. A duplicate case name raises DuplicateCase, a case the suite format refuses InputError; either way the
    file is left as it was."""
    path = suite_path(suites, suite)
    if path.is_file():
        try:
            data = yaml.safe_load(path.read_text()) or {}
        except yaml.YAMLError as exc:
            raise InputError(f"not YAML: {str(exc).splitlines()[0]}", path=path) from None
        if not isinstance(data, dict):
            raise InputError("not a suite (expected a mapping)", path=path)
    else:
        data = {"name": path.name.removesuffix(".yaml")}
    cases = data.get("cases") or []
    if not isinstance(cases, list):
        raise InputError("cases: expected a list", path=path)
    if any(isinstance(c, dict) and c.get("name") == case.name for c in cases):
        raise DuplicateCase(f"the suite already has a case named {case.name!r}", path=path)
    data["cases"] = [*cases, case_json(case, compact=True)]
    with atomic_path(path) as tmp:
        tmp.write_text(yaml.safe_dump(data, sort_keys=False, allow_unicode=True))
        try:
            load_suite(tmp)  # checked before it replaces the file
        except InputError as exc:
            raise InputError(exc.detail, path=path, where=exc.where) from None
    return path
