"""Run a scenario suite: every (case, seed) episode over an executor, results written as they finish, then the
reports (docs/testing.md, 'Scenario suites').

Every input is checked before anything is written (`check_run`: the planner spec imports, the planner command's
program exists, the executor is known; `preflight.check_cases`: every case's scene, ego and prompts as the env
checks them at reset). Episodes are `EpisodeTask`s (picklable: the planner travels as its spec or command, each
worker loads it and builds its own env) mapped by `langtraj.executors.EXECUTORS`; after each, `results.json` is
rewritten atomically, so nothing already written is lost when the run dies. At the end `report.md` and `junit.xml`
are written. A case the env still refuses at reset (what only the model can refuse) makes the run bad input once
the reports are written: one InputError naming the suite file, the case and the prompt. A worker that dies takes
its unfinished episodes with it: they are recorded as errors.
"""

from __future__ import annotations

import shlex
import shutil
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from langtraj.errors import InputError, one_line
from langtraj.executors import EXECUTORS
from langtraj.planners.base import DEFAULT_STEP_TIMEOUT_S
from langtraj.suites.config import Suite
from langtraj.suites.episode import DEFAULT_ENV, EpisodeResult, EpisodeTask, run_episode
from langtraj.suites.junit import write_junit
from langtraj.suites.preflight import check_cases, refused
from langtraj.suites.report import write_report
from langtraj.suites.results import SuiteResults


@dataclass(frozen=True)
class RunOptions:
    """How to run a suite: the planner (`planner`, a registered name or "module:Class", or `planner_cmd`, a
    command speaking the JSON-lines protocol; exactly one), the output folder, `workers` at a time on `executor`
    ("process" or "ray"), the per-call time limit `step_timeout` (s), whether failed episodes get a video, and
    the environment class ("module:Class")."""

    out: Path
    planner: str | None = None
    planner_cmd: str | None = None
    workers: int = 1
    executor: str = "process"
    step_timeout: float = DEFAULT_STEP_TIMEOUT_S
    video: bool = True
    env: str = field(default=DEFAULT_ENV)


def check_run(options: RunOptions) -> None:
    """Raise InputError for options that cannot run, before anything is written."""
    if (options.planner is None) == (options.planner_cmd is None):
        raise InputError("give exactly one of --planner and --planner-cmd", where="--planner")
    if options.planner is not None:
        from langtraj.planners import load_planner

        load_planner(options.planner)
    else:
        try:
            argv = shlex.split(options.planner_cmd or "")
        except ValueError as exc:
            raise InputError(f"cannot split {options.planner_cmd!r}: {exc}", where="--planner-cmd") from None
        if not argv:
            raise InputError("the planner command is empty", where="--planner-cmd")
        if shutil.which(argv[0]) is None:
            raise InputError(f"no program {argv[0]!r} (not on PATH, nor an executable file)", where="--planner-cmd")
    EXECUTORS.get(options.executor, where="--executor")
    if options.workers < 1:
        raise InputError(f"must be >= 1, got {options.workers}", where="--workers")
    if not options.step_timeout > 0:
        raise InputError(f"must be > 0, got {options.step_timeout}", where="--step-timeout")


def episode_tasks(suite: Suite, options: RunOptions) -> list[EpisodeTask]:
    """One task per (case, seed), in suite order."""
    return [
        EpisodeTask(
            suite=suite.name,
            case=case,
            seed=seed,
            planner=options.planner,
            planner_cmd=options.planner_cmd,
            step_timeout=options.step_timeout,
            out=Path(options.out),
            video=options.video,
            env=options.env,
        )
        for case in suite.cases
        for seed in case.seeds
    ]


def _lost(task: EpisodeTask, error: BaseException) -> EpisodeResult:
    """The result of an episode the executor lost (its worker died before returning it)."""
    reason = f"the worker was lost ({one_line(error)})"
    return EpisodeResult(case=task.case.name, seed=task.seed, status="error", reasons=[reason])


def run_suite(
    suite: Suite,
    options: RunOptions,
    on_result: Callable[[EpisodeResult], None] | None = None,
    on_warning: Callable[[str], None] | None = None,
    checked: bool = False,
) -> SuiteResults:
    """Run every episode of `suite`; `on_result` is called with each as it finishes, `on_warning` before any runs with
    each thing a case asks that its scene rules out (`preflight.check_cases`). Returns the results (also in
    `options.out`: results.json, report.md, junit.xml, videos/). Raises InputError for bad input: before anything is
    written, or after the reports when the env refused a case at reset. `checked`: the caller has run
    `preflight.check_cases` on the suite already (one suite under several planners)."""
    check_run(options)
    for warning in [] if checked else check_cases(suite, options.env):
        if on_warning is not None:
            on_warning(warning)
    out = Path(options.out)
    tasks = episode_tasks(suite, options)
    results = SuiteResults(
        suite, out, planner=options.planner, planner_cmd=options.planner_cmd, step_timeout=options.step_timeout
    )
    out.mkdir(parents=True, exist_ok=True)
    results.write()
    executor = EXECUTORS.create(options.executor)
    try:
        for result in executor.map(run_episode, tasks, options.workers, on_lost=_lost):
            results.add(result)
            results.write()
            if on_result is not None:
                on_result(result)
    except Exception as error:  # the executor broke (a worker died): what did not finish is an error
        for task in tasks:
            if (task.case.name, task.seed) not in results.episodes:
                results.add(_lost(task, error))
    finally:  # on Ctrl-C too: the reports say what finished
        results.write(finished=results.complete)
        write_report(results, out)
        write_junit(results, out)
    names = [case.name for case in suite.cases]
    for result in results.ordered():  # a case refused at reset: bad input, as if the pre-flight had found it
        if result.input_error is not None:
            raise refused(suite, names.index(result.case), *result.input_error)
    return results
