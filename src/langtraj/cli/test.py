"""`langtraj test SUITE.yaml --planner NAME|module:Class | --planner-cmd "CMD" | --calibrate [--seeds N] [--workers W]
[--executor process|ray] [--step-timeout S] [--no-video] --out DIR`.

Runs a planner through every case of a scenario suite (docs/testing.md, 'Scenario suites'): one episode per
(case, seed) in the LangTraj environment, judged by the case's criteria and by whether its prompts happened. DIR
receives `results.json` (rewritten after every finished episode), `report.md`, `junit.xml`,
`videos/<case>-seed<k>.mp4` of the episodes that did not pass, and `planner-logs/` (the stderr of a --planner-cmd
planner). With --calibrate, the suite runs under the IDM, the cautious and the constant-velocity planners, each into
DIR/<planner>/, and DIR/calibration.md says per case whether it separates the careful planner from the careless one
(`suites.calibration`; exit status 1 when a case that stages a scenario does not). Exit status 0 when every case
passes, 1 when any fails, errors or its scenario did not happen, 2 for bad
input (the suite file, the planner, the flags, a case the env refuses: its scene, ego or prompts, checked against
the scene by `suites.preflight`), found before anything is written; a prompt only the model refuses, at its
episode's reset, is bad input too, reported after the reports are written.

See README.md.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from langtraj.executors import EXECUTORS


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("test", help="run a planner through a scenario suite (results, report, JUnit XML)")
    p.add_argument("suite", metavar="SUITE", type=Path, help="suite file (YAML; configs/suites/example.yaml)")
    p.add_argument("--out", required=True, type=Path, help="output folder")
    driver = p.add_mutually_exclusive_group(required=True)
    driver.add_argument(
        "--planner",
        help="the planner: a registered name (idm, cautious, constant_velocity, log_replay) or package.module:Class",
    )
    driver.add_argument(
        "--planner-cmd",
        metavar="CMD",
        help='a planner in its own process speaking JSON lines on stdin/stdout, e.g. "python my_planner.py"',
    )
    driver.add_argument(
        "--calibrate",
        action="store_true",
        help="run the suite under idm, cautious and constant_velocity (OUT/<planner>/) and say per case whether it "
        "tells the careless planner from the careful one (OUT/calibration.md)",
    )
    p.add_argument("--seeds", type=int, metavar="N", help="run every case with seeds 0..N-1 (default: the suite's)")
    p.add_argument("--workers", type=int, default=1, help="episodes at a time (default 1)")
    p.add_argument(
        "--executor",
        default="process",
        choices=EXECUTORS.names(),
        help="where episodes run: process (a local pool, default) or ray (a Ray cluster)",
    )
    p.add_argument(
        "--step-timeout",
        type=float,
        default=None,
        metavar="S",
        help="seconds a planner may take per call before its case fails (default 10)",
    )
    p.add_argument("--no-video", action="store_true", help="no videos of the episodes that do not pass")
    p.add_argument(
        "--real-data",
        type=Path,
        metavar="DIR",
        help="the folder ${LANGTRAJ_REAL_DATA} names in the suite (default: that variable, else ../shared/data/real)",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from langtraj.suites import RunOptions, load_suite, run_suite
    from langtraj.suites.calibration import CALIBRATION_PLANNERS, calibrate, summary, write_calibration
    from langtraj.suites.episode import DEFAULT_ENV, EpisodeResult
    from langtraj.suites.preflight import check_cases
    from langtraj.suites.report import summary_line

    suite = load_suite(args.suite, real_data=args.real_data)
    if args.seeds is not None:
        suite = suite.with_seeds(args.seeds)

    def show(result: EpisodeResult) -> None:
        reason = f": {'; '.join(result.reasons)}" if result.reasons else ""
        print(
            f"{result.status.upper():5} {result.case} seed {result.seed} ({result.seconds:.1f} s){reason}", flush=True
        )

    def warn(warning: str) -> None:
        print(f"WARN  {warning}", file=sys.stderr, flush=True)

    def options(out: Path, planner: str | None) -> RunOptions:
        return RunOptions(
            out=out,
            planner=planner,
            planner_cmd=args.planner_cmd,
            workers=args.workers,
            executor=args.executor,
            video=not args.no_video,
            env=DEFAULT_ENV,
            **({} if args.step_timeout is None else {"step_timeout": args.step_timeout}),
        )

    if not args.calibrate:
        results = run_suite(suite, options(args.out, args.planner), on_result=show, on_warning=warn)
        print(f"{summary_line(results)} -> {args.out}")
        return 0 if results.passed else 1
    for warning in check_cases(suite, DEFAULT_ENV):  # once, for the three runs
        warn(warning)
    runs = {}
    for planner in CALIBRATION_PLANNERS:
        print(f"== {planner}", flush=True)
        runs[planner] = run_suite(suite, options(args.out / planner, planner), on_result=show, checked=True)
        print(f"{summary_line(runs[planner])} -> {args.out / planner}", flush=True)
    rows = calibrate(runs)
    write_calibration(args.out, rows)
    for row in rows:
        verdict = "n/a" if row.separates is None else ("separates" if row.separates else f"does not: {row.why}")
        print(f"{row.case}: {verdict}")
    print(f"{summary(rows)} -> {args.out / 'calibration.md'}")
    return 0 if all(r.separates is not False for r in rows) else 1
