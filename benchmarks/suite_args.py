"""The command line the suite benchmarks share (`timing_words.py`, `adversary_bystanders.py`, `staging_cost.py`,
`judging_cost.py`): a suite, the planner driving the ego, how many seeds and which cases, and bad input as one line
(an unknown case is an InputError naming it, `Suite.only`)."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path

from langtraj.errors import InputError
from langtraj.suites import Suite, load_suite


def suite_from_args(description: str, seeds: int) -> tuple[Suite, argparse.Namespace]:
    """The suite the command line asks for (its cases picked by `--cases`, each run with seeds 0..`--seeds`-1), and
    the parsed arguments (`planner` among them)."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("suite", type=Path)
    parser.add_argument("--planner", default="idm")
    parser.add_argument("--seeds", type=int, default=seeds)
    parser.add_argument("--cases", default="", help="comma-separated case names (default: every case)")
    args = parser.parse_args()
    suite = load_suite(args.suite)
    wanted = [c for c in args.cases.split(",") if c]
    return (suite.only(wanted) if wanted else suite).with_seeds(args.seeds), args


def run(main: Callable[[], int]) -> None:
    """Exits with `main`'s status; bad input (an unknown case, a bad suite) as one line and status 2, as the command
    line says it."""
    try:
        sys.exit(main())
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        sys.exit(2)
