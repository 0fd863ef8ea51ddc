"""`langtraj convert IN... OUT`: between WOMD TFRecords and ScenarioNet pickles, plain or zstd-compressed;
an IN that is a folder stands for every scenario file under it (docs/data.md says what each conversion
keeps)."""

from __future__ import annotations

import argparse
import re
from collections.abc import Iterator
from pathlib import Path

from langtraj.errors import InputError
from langtraj.fileio import ZSTD_SUFFIX
from langtraj.scenario.io import (
    available_formats,
    expand_scenario_paths,
    get_format,
    read_scenarios,
    write_scenarios,
)
from langtraj.scenario.model import Scenario


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "convert",
        help="convert scenario files between formats",
        description="Convert scenarios between formats. OUT is a file (its suffix names the format: "
        ".tfrecord for WOMD, .pkl for ScenarioNet, which holds one scenario per file) or a directory "
        "that gets one file per scenario (then --format is required). An IN that is a folder stands for "
        "every scenario file under it, searched recursively. Compressed inputs are read as they are; "
        "OUT is written zstd-compressed with --compress or when its name ends in .zst "
        "(e.g. convert shard.tfrecord shard.tfrecord.zst).",
    )
    p.add_argument("inputs", nargs="+", metavar="IN", help="scenario files, or folders searched recursively")
    p.add_argument("output", metavar="OUT")
    p.add_argument("--format", choices=available_formats(), help="output format (default: from OUT's suffix)")
    p.add_argument(
        "--compress",
        action="store_true",
        help="write zstd-compressed output (default when OUT ends in .zst; a folder OUT gets *.zst files)",
    )
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
        suffix = get_format(args.format).suffixes[0] + (ZSTD_SUFFIX if args.compress else "")
        written = 0
        for scenario in _all_scenarios(inputs):
            written += write_scenarios(out / f"{_safe_name(scenario.scenario_id)}{suffix}", [scenario], args.format)
        print(f"wrote {written} scenario(s) to {out}/")
        return 0
    written = write_scenarios(out, _all_scenarios(inputs), args.format, compress=args.compress or None)
    print(f"wrote {written} scenario(s) to {out}")
    return 0
