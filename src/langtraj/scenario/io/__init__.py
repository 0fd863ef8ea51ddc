"""Scenario files: format registry and the entry points every other module uses to read and write.

Importing this package registers the built-in formats (WOMD TFRecord, ScenarioNet pickle).

See docs/data.md.
"""

from __future__ import annotations

import importlib
from collections.abc import Iterable, Iterator
from pathlib import Path

from langtraj.fileio import ZSTD_SUFFIX
from langtraj.scenario.boxes import fix_box_sizes
from langtraj.scenario.io.base import (
    ScenarioFormat,
    available_formats,
    detect_format,
    expand_scenario_paths,
    format_for_output,
    get_format,
    register_format,
)
from langtraj.scenario.model import Scenario

for _module in ("womd", "scenarionet"):
    try:
        importlib.import_module(f"langtraj.scenario.io.{_module}")
    except ModuleNotFoundError as _exc:  # pragma: no cover - only while a format module is absent
        if _exc.name != f"langtraj.scenario.io.{_module}":
            raise


def read_scenarios(path: str | Path) -> Iterator[Scenario]:
    """Every scenario in `path`, streamed; the format is recognised from the file's content; boxes checked
    (`scenario.boxes.fix_box_sizes`)."""
    path = Path(path)
    return (fix_box_sizes(scenario, str(path)) for scenario in detect_format(path).read(path))


def read_scenario(path: str | Path, index: int = 0) -> Scenario:
    """The scenario at position `index` of `path`, its boxes checked (`scenario.boxes.fix_box_sizes`)."""
    path = Path(path)
    return fix_box_sizes(detect_format(path).read_one(path, index), str(path))


def write_scenarios(
    path: str | Path, scenarios: Iterable[Scenario], format_name: str | None = None, compress: bool | None = None
) -> int:
    """Write `scenarios` to `path` atomically in `format_name` (default: from the suffix), zstd-compressed
    when `compress` (default: when the name ends in `.zst`); every reader opens either transparently."""
    path = Path(path)
    if compress is None:
        compress = path.name.lower().endswith(ZSTD_SUFFIX)
    return format_for_output(path, format_name).write(path, scenarios, compress=compress)


__all__ = [
    "ScenarioFormat",
    "available_formats",
    "detect_format",
    "expand_scenario_paths",
    "format_for_output",
    "get_format",
    "read_scenario",
    "read_scenarios",
    "register_format",
    "write_scenarios",
]
