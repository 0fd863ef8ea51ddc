"""Running a job: the scene simulated closed loop with the job's prompts (and, to compare, without them) by the
simulation `langtraj simulate` runs (`sim.setup.build_policy`, `sim.engine.simulate`), the checkpoint loaded once
for every job, progress counted in replans; each run judged (`studio.results`), and the files written into the
job's folder, each atomically: `rollouts.npz` (the prompted run), then `result.json` (docs/studio.md, 'Jobs')."""

from __future__ import annotations

import json
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

from langtraj.errors import InputError
from langtraj.fileio import atomic_path
from langtraj.interdrive.adherence import AdherenceChecker
from langtraj.scenario.model import STEP_SECONDS
from langtraj.sim.config import SimConfig, SimRequest
from langtraj.sim.engine import replan_schedule, simulate
from langtraj.sim.policies import LoadedModel, Policy
from langtraj.sim.prompt_checks import check_prompts
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
        checks = check_prompts(scenario, case.prompts, case.adversary, case.target, scene.map_index)
        if not checks.ok:
            raise InputError(checks.first_error() or "the prompts cannot be run")
        report(0.0, "loading the model")
        loaded = self.model()
        runs = [("prompted", case.prompts)] + ([("unprompted", ())] if spec.compare else [])
        config = SimConfig(rollouts=spec.rollouts, seed=spec.seed)
        per_run = len(replan_schedule(scenario.current_index, config.replan_steps))
        total = per_run * len(runs)
        read = [(text, reading) for text in case.prompts for reading in read_prompts([text])]  # clause by clause
        checker = AdherenceChecker.build(scenario, map_index=scene.map_index) if case.prompts else None
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
            )
            if number == 0:
                result.rollouts.save(folder / ROLLOUTS_FILE)
        if stop.is_set():
            raise Interrupted
        body = {
            "start_step": scenario.current_index,
            "step_seconds": STEP_SECONDS,
            "runs": {"prompted": out["prompted"], "unprompted": out.get("unprompted")},
        }
        with atomic_path(folder / RESULT_FILE) as tmp:
            tmp.write_text(json.dumps(body, allow_nan=False))
