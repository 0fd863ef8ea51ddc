"""Runs a Python planner as a JSON-lines planner process: `python -m langtraj.planners.serve idm` or
`python -m langtraj.planners.serve package.module:Class` (docs/testing.md, 'Planners in another process').

Stdout carries protocol lines only (`langtraj.planners.jsonlines.serve`); a bad planner spec is one line on stderr
and exit status 2.
"""

from __future__ import annotations

import argparse
import sys

from langtraj.errors import InputError
from langtraj.planners.base import load_planner
from langtraj.planners.jsonlines import serve


def main(argv: list[str] | None = None) -> int:
    """Loads the planner `argv` names, builds it without arguments and serves it on stdin and stdout."""
    parser = argparse.ArgumentParser(
        prog="python -m langtraj.planners.serve", description="Serve a planner over the JSON-lines protocol."
    )
    parser.add_argument("planner", help='a registered planner name ("idm") or package.module:Class')
    args = parser.parse_args(argv)
    try:
        planner = load_planner(args.planner)()
    except InputError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    serve(planner)
    return 0


if __name__ == "__main__":
    sys.exit(main())
