"""Simulation jobs: their records (`Job`), one folder per job under the data folder with its `job.json` written
atomically (`JobStore`), and the queue with the one worker thread that runs them in order (`JobBoard`). Jobs
found at start-up keep their state: queued ones are queued again, one found running was cut off by a stop and
is marked interrupted. What a job computes is the runner's (`studio.simulation`) (docs/studio.md, 'Jobs')."""

from __future__ import annotations

import json
import queue
import secrets
import threading
from collections.abc import Callable
from dataclasses import dataclass, field, fields, replace
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, Literal, get_args

from langtraj.cases import Case, case_json, read_case
from langtraj.errors import InputError
from langtraj.fileio import atomic_path, read_json

Status = Literal["queued", "running", "done", "failed", "interrupted"]
STATUSES: tuple[str, ...] = get_args(Status)
JOB_FILE = "job.json"
INTERRUPTED = "the studio stopped while this job ran; submit it again"


class Interrupted(Exception):
    """Raised inside a running job when the studio stops (the job is left `interrupted`)."""


@dataclass(frozen=True)
class JobSpec:
    """What a job simulates: the `case` (its scene file, index and window, prompts, collision pair, seeds and
    checkpoint; `langtraj.cases.Case`) of the catalog's scene `scene` (scenario `scenario_id`), in `rollouts`
    rollouts, and whether the scene is also simulated without the prompts (`compare`). `planner`: the registered
    planner driving the ego, one env episode per seed of the case, exactly as `langtraj test --planner` runs them,
    so a saved case replays what was watched; None: every agent simulated, the ego too, as `langtraj simulate`."""

    scene: str
    scenario_id: str
    case: Case
    rollouts: int = 4
    compare: bool = True
    planner: str | None = None

    @property
    def seed(self) -> int:
        return self.case.seeds[0]


SPEC_KEYS = ("scene", "scenario_id", "rollouts", "compare", "planner")
"""The spec's fields a job record keeps beside its case (a record without `planner` ran every agent)."""


@dataclass(frozen=True)
class Job:
    """A job and where it stands: `status`, `progress` in [0, 1], the `stage` in words, the `error` of a failed
    or interrupted job, and its ISO times."""

    id: str
    spec: JobSpec
    status: Status = "queued"
    progress: float = 0.0
    stage: str = "queued"
    error: str | None = None
    created: str = field(default_factory=lambda: now())
    started: str | None = None
    finished: str | None = None

    def to_json(self) -> dict[str, Any]:
        """The job record (job.json, and the API's job): id, scene, scenario_id, rollouts, compare, planner, the case as
        `case_json` writes it, then where the job stands."""
        spec = {k: getattr(self.spec, k) for k in SPEC_KEYS}
        state = {f.name: getattr(self, f.name) for f in fields(self) if f.name not in ("id", "spec")}
        return {"id": self.id, **spec, "case": case_json(self.spec.case), **state}

    @classmethod
    def from_json(cls, data: dict[str, Any], where: str) -> Job:
        try:
            case = read_case(data["case"], where="case")
            spec = JobSpec(case=case, **{k: data[k] for k in SPEC_KEYS if k in data})
            rest = {k: v for k, v in data.items() if k in cls.__dataclass_fields__ and k not in ("id", "spec")}
            job = cls(id=str(data["id"]), spec=spec, **rest)
        except (KeyError, TypeError) as exc:
            raise InputError(f"not a job record ({exc})", path=where) from None
        except InputError as exc:
            raise exc.located(path=where) from None
        if job.status not in STATUSES:
            raise InputError(f"unknown status {job.status!r}", path=where)
        return job


def now() -> str:
    """ISO time to the microsecond, so jobs submitted within one second still list in the order they came."""
    return datetime.now(UTC).isoformat(timespec="microseconds")


def new_job_id() -> str:
    """Unique, and sortable by creation second: 20270101-120000-a1b2c3 (the order within a second is `created`'s)."""
    return f"{datetime.now(UTC):%Y%m%d-%H%M%S}-{secrets.token_hex(3)}"


class JobStore:
    """The job folders under `root` (`root/<id>/job.json` and the job's result files)."""

    def __init__(self, root: Path):
        self.root = Path(root)

    def folder(self, job_id: str) -> Path:
        return self.root / job_id

    def save(self, job: Job) -> None:
        with atomic_path(self.folder(job.id) / JOB_FILE) as tmp:
            tmp.write_text(json.dumps(job.to_json(), indent=1))

    def load_all(self) -> tuple[list[Job], list[str]]:
        """Every job on disk, oldest first, and one line per folder that holds no readable job. Temporary files a
        killed process left behind are removed (every write is atomic, so they are never results)."""
        jobs, problems = [], []
        if not self.root.is_dir():
            return jobs, problems
        for folder in sorted(p for p in self.root.iterdir() if p.is_dir() and not p.name.startswith(".")):
            for stray in folder.glob(".*.tmp*"):
                stray.unlink(missing_ok=True)
            path = folder / JOB_FILE
            try:
                jobs.append(Job.from_json(read_json(path, "no job record"), str(path)))
            except (OSError, ValueError, InputError) as exc:
                problems.append(f"{path}: {exc}")
        return sorted(jobs, key=lambda j: (j.created, j.id)), problems


Report = Callable[[float, str], None]
Runner = Callable[[Job, Path, Report, threading.Event], None]
"""Runs a job: writes its result files into the folder, reports (progress, stage) as it goes, raises
`Interrupted` when the event is set, InputError (or anything) when it fails."""


class JobBoard:
    """Every job of the studio, persisted by `store`, and the worker that runs the queued ones in order."""

    def __init__(self, store: JobStore, runner: Runner):
        self.store, self.runner = store, runner
        self._jobs: dict[str, Job] = {}
        self._lock = threading.Lock()
        self._queue: queue.Queue[str | None] = queue.Queue()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        loaded, self.problems = store.load_all()
        for job in loaded:
            if job.status == "running":
                job = replace(job, status="interrupted", error=INTERRUPTED, stage="interrupted", finished=now())
                store.save(job)
            self._jobs[job.id] = job
            if job.status == "queued":
                self._queue.put(job.id)

    # ------------------------------------------------------------------ reading
    def jobs(self) -> list[Job]:
        """Newest first."""
        with self._lock:
            return sorted(self._jobs.values(), key=lambda j: (j.created, j.id), reverse=True)

    def get(self, job_id: str) -> Job | None:
        with self._lock:
            return self._jobs.get(job_id)

    def folder(self, job_id: str) -> Path:
        return self.store.folder(job_id)

    # ------------------------------------------------------------------ writing
    def submit(self, spec: JobSpec) -> Job:
        job = Job(new_job_id(), spec)
        self._update(job)
        self._queue.put(job.id)
        return job

    def _update(self, job: Job) -> Job:
        with self._lock:
            self.store.save(job)
            self._jobs[job.id] = job
        return job

    # ------------------------------------------------------------------ the worker
    def start(self) -> None:
        """Start the worker thread (once)."""
        if self._thread is None:
            self._thread = threading.Thread(target=self._work, name="studio-worker", daemon=True)
            self._thread.start()

    def close(self, timeout: float | None = 30.0) -> None:
        """Stop the worker: a running job is interrupted at its next replan and left `interrupted`."""
        self._stop.set()
        self._queue.put(None)
        if self._thread is not None:
            self._thread.join(timeout)

    def _work(self) -> None:
        while not self._stop.is_set():
            job_id = self._queue.get()
            if job_id is None or self._stop.is_set():
                return
            job = self.get(job_id)
            if job is not None and job.status == "queued":
                self.run(job)

    def run(self, job: Job) -> Job:
        """Run one job now, in this thread (the worker's loop; tests call it directly)."""
        job = self._update(replace(job, status="running", started=now(), stage="starting", progress=0.0))
        holder = {"job": job}

        def report(progress: float, stage: str) -> None:
            holder["job"] = self._update(replace(holder["job"], progress=min(max(progress, 0.0), 1.0), stage=stage))

        try:
            self.runner(job, self.store.folder(job.id), report, self._stop)
        except Interrupted:
            final = replace(holder["job"], status="interrupted", error=INTERRUPTED, stage="interrupted")
        except InputError as exc:
            final = replace(holder["job"], status="failed", error=str(exc), stage="failed")
        except Exception as exc:  # a job's failure is reported on the job; the worker goes on
            line = str(exc).splitlines()[0] if str(exc) else ""
            final = replace(holder["job"], status="failed", error=f"{type(exc).__name__}: {line}", stage="failed")
        else:
            final = replace(holder["job"], status="done", progress=1.0, stage="done")
        return self._update(replace(final, finished=now()))
