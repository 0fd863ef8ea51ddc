"""`langtraj convert IN... OUT`: between WOMD TFRecords and ScenarioNet pickles; an IN that is a folder
stands for every scenario file under it (docs/data.md says what each conversion keeps)."""

from __future__ import annotations

import argparse
import re
from collections.abc import Iterator
from pathlib import Path

from langtraj.errors import InputError
from langtraj.scenario.io import (
    available_formats,
    expand_scenario_paths,
    format_for_output,
    get_format,
    read_scenarios,
)
from langtraj.scenario.model import Scenario


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "convert",
        help="convert scenario files between formats",
        description="Convert scenarios between formats. OUT is a file (its suffix names the format: "
        ".tfrecord for WOMD, .pkl for ScenarioNet, which holds one scenario per file) or a directory "
        "that gets one file per scenario (then --format is required). An IN that is a folder stands for "
        "every scenario file under it, searched recursively.",
    )
    p.add_argument("inputs", nargs="+", metavar="IN", help="scenario files, or folders searched recursively")
    p.add_argument("output", metavar="OUT")
    p.add_argument("--format", choices=available_formats(), help="output format (default: from OUT's suffix)")
    p.set_defaults(func=run)


def _all_scenarios(paths: list[Path]) -> Iterator[Scenario]:
    for path in paths:
        yield from read_scenarios(path)


def _safe_name(scenario_id: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]", "_", scenario_id) or "scenario"


def run(args: argparse.Namespace) -> int:
    out = Path(args.output)
    inputs = expand_scenario_paths(args.inputs)
    for path in inputs:  # fail before writing anything when an input is missing
        if not path.is_file():
            raise InputError("no such file", path=path)
    if out.is_dir() or (not out.suffix and args.format):
        if not args.format:
            raise InputError("OUT is a directory: name the output format with --format", path=out)
        fmt = get_format(args.format)
        written = 0
        for scenario in _all_scenarios(inputs):
            target = out / f"{_safe_name(scenario.scenario_id)}{fmt.suffixes[0]}"
            written += fmt.write(target, [scenario])
        print(f"wrote {written} scenario(s) to {out}/")
        return 0
    written = format_for_output(out, args.format).write(out, _all_scenarios(inputs))
    print(f"wrote {written} scenario(s) to {out}")
    return 0
