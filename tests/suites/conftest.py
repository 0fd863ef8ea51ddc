"""Shared pieces of the suite tests: fake scenes and a suite file over them."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from suites.fakes import write_scene


def write_suite(folder: Path, cases: list[dict], name: str = "fake", **top) -> Path:
    path = folder / "suite.yaml"
    path.write_text(yaml.safe_dump({"name": name, **top, "cases": cases}))
    return path


@pytest.fixture
def two_case_suite(tmp_path: Path) -> Path:
    """A suite of a "good" and a "bad" fake scene (the test planners misbehave in the bad one), one seed each."""
    write_scene(tmp_path, "good")
    write_scene(tmp_path, "bad")
    return write_suite(
        tmp_path, [{"name": "good-case", "scenario": "good.json"}, {"name": "bad-case", "scenario": "bad.json"}]
    )
