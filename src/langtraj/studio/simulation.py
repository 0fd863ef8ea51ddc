"""Running a job: the scene simulated closed loop with the job's prompts (and, to compare, without them). With a
planner, each rollout is the env episode `langtraj test --planner` runs for one seed of the job's case
(`suites.episode.run_episode`: the same env, seed and planner), so a case saved from the job replays what was
watched; without one, every agent is simulated by the simulation `langtraj simulate` runs (`sim.setup.build_policy`,
`sim.engine.simulate`), the checkpoint loaded once for every job, progress counted in replans. Each run is judged
(`studio.results`), and the files written into the job's folder, each atomically: `rollouts.npz` (the prompted run),
then `result.json` (docs/studio.md, 'Jobs')."""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from langtraj.cases import Case
from langtraj.env.environment import ego_row
from langtraj.errors import InputError
from langtraj.fileio import atomic_path
from langtraj.interdrive.adherence import AdherenceChecker
from langtraj.interdrive.reader import PromptReading
from langtraj.planners import PLANNERS
from langtraj.roads import MapIndex
from langtraj.rollouts.container import Rollouts
from langtraj.scenario.model import STEP_SECONDS, Scenario
from langtraj.sim.config import SimConfig, SimRequest
from langtraj.sim.engine import replan_schedule, simulate
from langtraj.sim.policies import LoadedModel, Policy
from langtraj.sim.prompt_checks import PromptChecks, check_prompts
from langtraj.sim.prompts import read_prompts
from langtraj.sim.setup import build_policy
from langtraj.sim.world import SimWorld
from langtraj.studio.catalog import Catalog
from langtraj.studio.jobs import Interrupted, Job, Report
from langtraj.studio.results import run_json

RESULT_FILE = "result.json"
ROLLOUTS_FILE = "rollouts.npz"


class CountedPolicy(Policy):
    """A built policy with a hook before and after each of its replans (progress, and stopping mid-run);
    everything else is the wrapped policy's."""

    name = "counted"

    def __init__(self, inner: Policy, before: Callable[[], None], after: Callable[[], None]):
        self.inner, self.before, self.after = inner, before, after
        self.undriven = inner.undriven

    def drives(self, scenario, sim_agents):  # type: ignore[no-untyped-def]
        return self.inner.drives(scenario, sim_agents)

    def describe(self) -> dict[str, Any]:
        return self.inner.describe()

    def reset(self, world: SimWorld, seed: int) -> Any:
        return self.inner.reset(world, seed)

    def plan(self, world: SimWorld, state: Any, step: int, horizon: int):  # type: ignore[no-untyped-def]
        self.before()
        plan = self.inner.plan(world, state, step, horizon)
        self.after()
        return plan

    def report(self, world: SimWorld, state: Any) -> dict[str, Any]:
        return self.inner.report(world, state)


class JobRunner:
    """Runs studio jobs on the scenes of `catalog` with the model of `checkpoint` (None: the shipped one), loaded
    on the first job."""

    def __init__(self, catalog: Catalog, checkpoint: Path | None = None):
        self.catalog, self.checkpoint = catalog, checkpoint
        self._loaded: LoadedModel | None = None
        self._lock = threading.Lock()

    def model(self) -> LoadedModel:
        with self._lock:
            if self._loaded is None:
                from langtraj.model.checkpoint import load_model
                from langtraj.sim.checkpoints import shipped_checkpoint

                self._loaded = load_model(self.checkpoint or shipped_checkpoint())
            return self._loaded

    def __call__(self, job: Job, folder: Path, report: Report, stop: threading.Event) -> None:
        spec, case = job.spec, job.spec.case
        scene = self.catalog.load(spec.scene)
        if scene is None:
            raise InputError(f"no scene {spec.scene!r} in this studio's catalog (started with other files?)")
        if case.checkpoint != self.checkpoint:
            asked, runs = (str(path or "the shipped checkpoint") for path in (case.checkpoint, self.checkpoint))
            raise InputError(f"this job asks for {asked}; the studio runs {runs} (start it with that checkpoint)")
        scenario = scene.scenario
        checks = job_checks(scenario, case.prompts, case.adversary, case.target, spec.planner, scene.map_index)
        if not checks.ok:
            raise InputError(checks.first_error() or "the prompts cannot be run")
        runs = [("prompted", case.prompts)] + ([("unprompted", ())] if spec.compare else [])
        # every run is judged on the job's prompts, clause by clause (the unprompted one gives the base rate)
        read = [(text, reading) for text in case.prompts for reading in read_prompts([text])]
        checker = AdherenceChecker.build(scenario, map_index=scene.map_index) if case.prompts else None
        if spec.planner is not None:
            self._episodes(job, scenario, runs, read, checker, folder, report, stop)
            return
        report(0.0, "loading the model")
        loaded = self.model()
        config = SimConfig(rollouts=spec.rollouts, seed=spec.seed)
        per_run = len(replan_schedule(scenario.current_index, config.replan_steps))
        total = per_run * len(runs)
        out: dict[str, Any] = {}
        done = 0
        for number, (name, prompts) in enumerate(runs):
            count = 0

            def before() -> None:
                if stop.is_set():
                    raise Interrupted
                report(done / total, f"{name} run {count + 1}/{per_run} replans")  # noqa: B023 - read at call time

            def after() -> None:
                nonlocal count, done
                count += 1
                done += 1

            request = SimRequest(
                checkpoint=case.checkpoint, prompts=tuple(prompts), adversary=case.adversary, target=case.target
            )
            policy, _ = build_policy(scenario, request, loaded)
            result = simulate(scenario, CountedPolicy(policy, before, after), config)
            report(done / total, f"judging the {name} run")
            out[name] = run_json(
                scenario,
                result.rollouts,
                [text for text, _ in read],
                [reading for _, reading in read],
                checker,
                result.report,
                result.seconds,
                aims=out["prompted"]["targets"] if number else None,
            )
            if number == 0:
                result.rollouts.save(folder / ROLLOUTS_FILE)
        if stop.is_set():
            raise Interrupted
        _write_result(folder, scenario, out)

    def _episodes(
        self,
        job: Job,
        scenario: Scenario,
        runs: list[tuple[str, Sequence[str]]],
        read: list[tuple[str, PromptReading]],
        checker: AdherenceChecker | None,
        folder: Path,
        report: Report,
        stop: threading.Event,
    ) -> None:
        """Each run as one env episode per seed of the job's case under its planner (`run_episode`, as `langtraj
        test` runs it in one process); an episode that does not run its whole length fails the job with its reason."""
        from langtraj.suites.episode import EpisodeTask, run_episode

        spec = job.spec
        total, done, out = len(runs) * len(spec.case.seeds), 0, {}
        for number, (name, prompts) in enumerate(runs):
            case = spec.case if prompts else replace(spec.case, prompts=(), adversary=None, target=None)
            kept = _Kept()
            results = []
            start = time.perf_counter()
            for seed in case.seeds:
                if stop.is_set():
                    raise Interrupted
                report(done / total, f"{name} run, seed {seed}: episode under the {spec.planner} planner")
                task = EpisodeTask("studio", case, seed, spec.planner, None, 0.0, folder, video=False)

                result = run_episode(task, kept)
                if result.status == "error" or _short(result, case):
                    why = "; ".join(result.reasons) or "the episode ended early"
                    raise InputError(f"{name} run, seed {seed}: {why}")
                results.append(result)
                done += 1
            rollouts = _stacked(kept.rollouts)
            out[name] = run_json(
                scenario,
                rollouts,
                [text for text, _ in read],
                [reading for _, reading in read],
                checker,
                kept.reports[0],  # the others' report: the prompts' targets and warnings
                time.perf_counter() - start,
                aims=out["prompted"]["targets"] if number else None,
            ) | {"episodes": [_episode_json(r) for r in results], "planner": spec.planner}
            if number == 0:
                rollouts.save(folder / ROLLOUTS_FILE)
        if stop.is_set():
            raise Interrupted
        _write_result(folder, scenario, out)


def job_checks(
    scenario: Scenario,
    prompts: Sequence[str],
    adversary: int | None,
    target: int | None,
    planner: str | None,
    index: MapIndex,
) -> PromptChecks:
    """The one prompt check (`sim.prompt_checks`) for a job: with a planner, against the ego the env gives it (a
    registered planner only), as the env checks before its episode."""
    ego = None
    if planner is not None:
        PLANNERS.get(planner, where="planner")
        ego = int(scenario.agents.ids[ego_row(scenario)])
    return check_prompts(scenario, prompts, adversary, target, index, ego=ego)


class _Kept:
    """What a job keeps of each episode it watched: the env's rollout and its simulation report."""

    def __init__(self) -> None:
        self.rollouts: list[Rollouts] = []
        self.reports: list[dict[str, Any]] = []

    def __call__(self, env: Any) -> None:
        self.rollouts.append(env.rollout())
        self.reports.append(env.simulation_report())


def _short(result: Any, case: Case) -> bool:
    """Whether an episode stopped before its end (the planner failed): its rollout would show steps never run."""
    return len(result.steps.get("collision", [])) < case.steps


def _stacked(kept: list[Rollouts]) -> Rollouts:
    """One rollout per episode, as one container (the same scene: the same agents in the same order)."""
    first = kept[0]
    stack = {name: np.concatenate([getattr(r, name) for r in kept]) for name in ("x", "y", "z", "heading")}
    return Rollouts(first.object_id, **stack, scenario_id=first.scenario_id, log_following_ids=first.log_following_ids)


def _episode_json(result: Any) -> dict[str, Any]:
    """What the page shows of an episode: its seed, verdict and reasons, the ego and each prompt's verdict."""
    data = result.to_json()
    return {k: data[k] for k in ("seed", "status", "reasons", "ego", "prompts", "reads_log")}


def _write_result(folder: Path, scenario: Scenario, out: dict[str, Any]) -> None:
    body = {
        "start_step": scenario.current_index,
        "step_seconds": STEP_SECONDS,
        "runs": {"prompted": out["prompted"], "unprompted": out.get("unprompted")},
    }
    with atomic_path(folder / RESULT_FILE) as tmp:
        tmp.write_text(json.dumps(body, allow_nan=False))
