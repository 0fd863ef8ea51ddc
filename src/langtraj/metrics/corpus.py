"""Scoring many scenarios: pairs each scenario with its rollout file, scores them in parallel, averages.

Rollout files are matched to scenarios by name: `<scenario_id>.npz` in a rollout folder. Each pair is an
independent job for an executor (`langtraj.executors`), so a corpus scores on a local process pool or
a Ray cluster alike. The corpus figure of every field is the mean over scenarios, as in the challenge.

See docs/metrics.md.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, fields
from pathlib import Path

from tqdm import tqdm

from langtraj.errors import InputError
from langtraj.executors import EXECUTORS
from langtraj.metrics.wosac import ScenarioMetrics, evaluate_scenario
from langtraj.rollouts.container import Rollouts
from langtraj.scenario.io import read_scenario, read_scenarios


@dataclass(frozen=True)
class EvalJob:
    """One scenario (file and position in it) and the rollout file to score against it."""

    scenario_file: str
    index: int
    rollouts_file: str
    config: str = "2025"


def run_job(job: EvalJob) -> ScenarioMetrics:
    """Score one job; errors name the files involved."""
    scenario = read_scenario(job.scenario_file, job.index)
    rollouts = Rollouts.load(job.rollouts_file)
    try:
        return evaluate_scenario(scenario, rollouts, job.config)
    except InputError as exc:
        raise exc.located(path=job.rollouts_file, where=f"scenario {scenario.scenario_id}") from None


def pair_jobs(scenarios: Iterable[str | Path], rollouts_dir: str | Path, config: str = "2025") -> list[EvalJob]:
    """A job for every scenario whose `<scenario_id>.npz` is in `rollouts_dir`.

    A rollout file that matches no scenario is an error (it usually means the wrong folder), and so
    is finding no pair at all.
    """
    rollouts_dir = Path(rollouts_dir)
    available = {p.stem: p for p in rollouts_dir.glob("*.npz")}
    jobs, seen = [], set()
    for file in scenarios:
        for index, scenario in enumerate(read_scenarios(file)):
            match = available.get(scenario.scenario_id)
            if match is not None:
                jobs.append(EvalJob(str(file), index, str(match), config))
                seen.add(scenario.scenario_id)
    unmatched = sorted(set(available) - seen)
    if unmatched:
        shown = ", ".join(unmatched[:5]) + (f", ... ({len(unmatched)} in all)" if len(unmatched) > 5 else "")
        raise InputError(f"rollouts for scenarios that are not in the scenario files: {shown}", path=rollouts_dir)
    if not jobs:
        raise InputError("no <scenario_id>.npz file matches a scenario", path=rollouts_dir)
    return jobs


def aggregate(results: Sequence[ScenarioMetrics]) -> dict[str, float]:
    """The mean of every numeric field over scenarios (NaN fields are left out of their mean)."""
    out: dict[str, float] = {}
    for f in fields(ScenarioMetrics):
        values = [getattr(r, f.name) for r in results]
        if isinstance(values[0], float):
            finite = [v for v in values if not math.isnan(v)]
            out[f.name] = sum(finite) / len(finite) if finite else float("nan")
    return out


def evaluate_corpus(
    jobs: Sequence[EvalJob], *, workers: int = 1, executor: str = "process", progress: bool = True
) -> list[ScenarioMetrics]:
    """Score every job, `workers` at a time; results in job order."""
    engine = EXECUTORS.create(executor, where="executor")
    order = {(j.scenario_file, j.index): i for i, j in enumerate(jobs)}
    results: list[ScenarioMetrics | None] = [None] * len(jobs)
    bar = tqdm(total=len(jobs), desc="scoring", unit="scenario", disable=not progress or None)
    try:
        for job, metrics in engine.map(_run_keyed, list(jobs), workers):
            results[order[(job.scenario_file, job.index)]] = metrics
            bar.update(1)
    finally:
        bar.close()
    return [r for r in results if r is not None]


def _run_keyed(job: EvalJob) -> tuple[EvalJob, ScenarioMetrics]:
    return job, run_job(job)
