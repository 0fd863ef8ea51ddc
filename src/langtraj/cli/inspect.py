"""`langtraj inspect FILE|DIR... [--json]`: what is in scenario files (folders are searched recursively;
docs/data.md lists the formats)."""

from __future__ import annotations

import argparse
import json
import sys

from langtraj.scenario.io import expand_scenario_paths, read_scenarios
from langtraj.scenario.summary import scenario_summary


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("inspect", help="summarize the scenarios in files (WOMD TFRecord, ScenarioNet)")
    p.add_argument("files", nargs="+", metavar="FILE|DIR", help="scenario files, or folders searched recursively")
    p.add_argument("--json", action="store_true", help="print a JSON list, one object per scenario")
    p.set_defaults(func=run)


def _text(summary: dict, path: str, index: int) -> str:
    types = ", ".join(f"{k} {v}" for k, v in summary["agent_type_counts"].items() if v)
    return (
        f"{path} [{index}] {summary['scenario_id']} ({summary['source_format']}): "
        f"{summary['num_agents']} agents ({types}), {summary['num_map_features']} map features, "
        f"{summary['num_steps']} steps, current index {summary['current_index']}, sdc {summary['sdc_id']}, "
        f"objects of interest {summary['objects_of_interest']}, "
        f"tracks to predict {summary['tracks_to_predict']}"
    )


def run(args: argparse.Namespace) -> int:
    summaries = []
    for path in map(str, expand_scenario_paths(args.files)):
        for index, scenario in enumerate(read_scenarios(path)):
            summary = {"file": path, "index": index, **scenario_summary(scenario)}
            if args.json:
                summaries.append(summary)
            else:
                print(_text(summary, path, index), flush=True)
    if args.json:
        json.dump(summaries, sys.stdout, indent=2)
        sys.stdout.write("\n")
    return 0
