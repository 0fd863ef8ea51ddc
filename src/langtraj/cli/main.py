"""Entry point of the `langtraj` command: parses the verb, runs it, turns errors into one line. See README.md."""

from __future__ import annotations

import argparse
import os
import sys
import warnings
from collections.abc import Callable, Sequence

from langtraj import __version__
from langtraj.cli import (
    baseline,
    convert,
    demo,
    evaluate,
    experiment,
    features,
    inspect,
    interdrive,
    label,
    recipe,
    render,
    sample,
    simulate,
    studio,
    submit,
    suggest,
    synth,
    test,
    train,
)
from langtraj.errors import DataWarning, LangTrajError

VERBS = (
    inspect,
    render,
    convert,
    synth,
    interdrive,
    features,
    label,
    baseline,
    evaluate,
    submit,
    train,
    recipe,
    sample,
    simulate,
    demo,
    experiment,
    suggest,
    test,
    studio,
)
"""Each verb module has `add_parser(subparsers)` (setting `func`) and a `run(args) -> int`."""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="langtraj", description="Language-conditioned multi-agent traffic simulation."
    )
    parser.add_argument("--version", action="version", version=f"langtraj {__version__}")
    subparsers = parser.add_subparsers(dest="verb", required=True, metavar="VERB")
    for verb in VERBS:
        verb.add_parser(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command; exit status 0 on success, 2 on bad input or usage, 1 when the system refuses a
    read or write, 130 on Ctrl-C."""
    args = build_parser().parse_args(argv)
    try:
        with warnings.catch_warnings():  # restores the warning display on the way out (in-process callers)
            warnings.showwarning = _data_warnings_as_lines(args.verb, warnings.showwarning)
            return int(args.func(args) or 0)
    except LangTrajError as exc:
        print(f"langtraj {args.verb}: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # the reader left, e.g. `langtraj inspect ... | head`: not an error (before OSError,
        _silence_stdout()  # its base class); nothing more can be written, not even at exit
        return 0
    except OSError as exc:  # the machine refused (disk full, permissions, a file where a folder must be)
        print(f"langtraj {args.verb}: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"langtraj {args.verb}: interrupted", file=sys.stderr)
        return 130


def _data_warnings_as_lines(verb: str, shown: Callable) -> Callable:
    """A warning display printing a `DataWarning` (input LangTraj repaired as it read it) as one line naming the
    verb, as errors are printed; other warnings go to `shown`, Python's own format."""

    def show(message, category, filename, lineno, file=None, line=None):  # type: ignore[no-untyped-def]
        if issubclass(category, DataWarning):
            print(f"langtraj {verb}: warning: {message}", file=sys.stderr)
        else:
            shown(message, category, filename, lineno, file, line)

    return show


def _silence_stdout() -> None:
    """Point standard output at /dev/null, so the interpreter's flush at exit does not fail on the closed pipe."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, sys.stdout.fileno())
    os.close(devnull)


if __name__ == "__main__":
    sys.exit(main())
