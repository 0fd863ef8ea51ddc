"""Load and a crash of the labeling server: concurrent annotators against `langtraj label serve`.

Starts the real server (`python -m langtraj.cli.main label serve`, a subprocess on a free loopback port)
over SQLite and over PostgreSQL (a throwaway server, `langtraj.labeling.devdb.TemporaryPostgres`; skipped
with the reason where PostgreSQL is not installed), and lets `--annotators` clients (asyncio + httpx, one
cookie jar and one connection each, no think time) log in and loop "claim the next task, submit random
valid labels for its pair" for `--seconds` of wall time. A client records every claim (slot, its own send
and receive times, the lock's expiry the server returned) and every acknowledged submit (201 or 200:
slot, submission id, annotation id, the labels sent). About `--resend` of the acknowledged submits are
sent a second time with the same submission id, as a browser does when a response is lost; the server
must answer 200 with the first copy's id.

Faults (`--kill-at`, seconds into the load; 0 turns them off): `--ghosts` extra annotators (logged in
with the others) each claim a slot and vanish, timed so that their locks (`--lock-minutes`, default 15 s,
far longer than any hold of the load) expire about 1 s after the kill. The server is killed with SIGKILL
at `--kill-at`, the benchmark waits until the ghosts' locks have expired, restarts the server on the same
port and database, and holds the clients back until it has checked in the database that every slot whose
lock expired before the restart is open again (the server releases expired locks at start) while every
lock that had not expired is still held by its annotator. Clients whose request died with the server
retry it (the same submission id) once the server is back; the load goes on for at least AFTER_RESTART
seconds after the restart, past `--seconds` if need be.

Afterwards the database itself is checked (SQLAlchemy on the same URL), and each check prints PASS/FAIL
(exit status 1 on any FAIL):
- no loss: every acknowledged submit is an annotation with that id, submission id, annotator, slot and
  exactly the labels sent (those acknowledged before the kill counted apart);
- no duplicates: one annotation per slot and per (task, annotator), at most `overlap` per task, the
  annotations of the load's annotators are exactly the acknowledged submissions, and every resend got
  the first copy back;
- no slot held twice: no two annotators' claims of a slot overlap in time ([claim sent, submit answered])
  unless the first one's lock had expired when the second was granted;
- faults: expired locks open after the restart, unexpired ones kept, and each released slot later claimed
  by another annotator;
- no 5xx answer, and no 4xx but a submit refused after its lock expired (403/409) or a claim refused
  for contention (409); every client finished.

Figures: submit latency p50/p95 (ms, client side, from sending the submit to its answer, excluding
submits that had to be retried across the restart), claim latency p50/p95, new annotations per second
over the load's wall time (the downtime included), claims, resends, answers other than 2xx by endpoint
and status.

Tasks: `langtraj.labeling.demo.prepare_demo` synthesizes `--windows` SUMO windows (seconds) and adds them
as tasks (or `--dataset` gives the windows); the other tasks are copies of those windows' task rows
(agents, pair, suggestions) under new scenario ids `{window}~{n}`, written to the database only (the load
never asks for a window's video or positions, the only requests that read the dataset). There are enough
for `--max-submissions`, the hard cap on acknowledged submits; a client that finds no task left stops and
is reported.

    python benchmarks/label_load.py [--backend sqlite|postgresql|both] [--annotators 50] [--seconds 120]
        [--kill-at 60 (0: no kill)] [--lock-minutes 0.25] [--ghosts 5] [--overlap 2] [--max-submissions 20000]
        [--dataset DIR] [--seed 0] [--keep DIR]
"""

from __future__ import annotations

import argparse
import asyncio
import math
import os
import platform
import random
import secrets
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections import Counter, defaultdict
from collections.abc import Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import httpx
import numpy as np
from sqlalchemy import insert, select

from langtraj.interdrive.taxonomy import SUBTYPES
from langtraj.labeling.auth import create_user
from langtraj.labeling.db import Database, utcnow
from langtraj.labeling.demo import prepare_demo
from langtraj.labeling.models import Annotation, Role, Slot, SlotState, Task, User
from langtraj.labeling.tasks import add_tasks

PASSWORD = secrets.token_urlsafe(12)
REQUEST_TIMEOUT = 60.0
"""Seconds a client waits for one answer; a longer wait counts as a lost connection and is retried."""
GHOST_EXPIRY_AFTER_KILL = 1.0
"""The ghosts' locks expire this long after the kill: while the server is down."""
MAX_DOWNTIME = 90.0
"""Longest wait for the ghosts' locks to expire after the kill; a longer one is refused up front."""
AFTER_RESTART = 2.0
"""The load goes on at least this long after the restart (longer than --seconds if need be), so that the
slots the restart released get claimed again."""
GRACE = 60.0
"""Seconds the clients get after --seconds to finish their submit in flight before they are cancelled."""
AGREE = ("other/no_interaction", "other/no_interaction")
"""Half of the submits use these labels so that some tasks reach consensus (review.settle accepts them)."""


# ---------------------------------------------------------------- the server


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Server:
    """`langtraj label serve` as a subprocess on 127.0.0.1:`port`; restartable on the same port."""

    def __init__(self, dataset: Path, url: str, lock_minutes: float, log: Path):
        self.dataset, self.url, self.lock_minutes, self.log = dataset, url, lock_minutes, log
        self.port = free_port()
        self.process: subprocess.Popen[bytes] | None = None

    @property
    def base(self) -> str:
        return f"http://127.0.0.1:{self.port}"

    def start(self, timeout: float = 60.0) -> float:
        """Start the server and wait until /healthz answers; returns the seconds that took."""
        t0 = time.perf_counter()
        cmd = [sys.executable, "-m", "langtraj.cli.main", "label", "serve", str(self.dataset), "--db", self.url,
               "--host", "127.0.0.1", "--port", str(self.port), "--lock-minutes", str(self.lock_minutes)]  # fmt: skip
        with open(self.log, "ab") as log:
            self.process = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.process.poll() is not None:
                raise RuntimeError(f"the server exited with {self.process.returncode}:\n{self.log_tail()}")
            try:
                if httpx.get(f"{self.base}/healthz", timeout=2.0).status_code == 200:
                    return time.perf_counter() - t0
            except httpx.TransportError:
                pass
            time.sleep(0.05)
        self.kill()
        raise RuntimeError(f"the server did not answer within {timeout:.0f} s:\n{self.log_tail()}")

    def kill(self) -> None:
        """SIGKILL, no chance to clean up (the process group: the server has no children, but be sure)."""
        if self.process is not None and self.process.poll() is None:
            os.killpg(self.process.pid, signal.SIGKILL)
            self.process.wait()

    def stop(self) -> None:
        if self.process is not None and self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(timeout=15)
            except subprocess.TimeoutExpired:
                self.kill()

    def log_tail(self, chars: int = 3000) -> str:
        try:
            return self.log.read_text(errors="replace")[-chars:]
        except FileNotFoundError:
            return ""


# ---------------------------------------------------------------- the dataset and the database


def prepare(
    folder: Path, url: str, windows: int, tasks: int, overlap: int, users: Sequence[str], dataset: Path | None = None
) -> Path:
    """The windows of `dataset` (default: `windows` demo windows synthesized into `folder`) as tasks, copies of
    their task rows up to `tasks` tasks, and the load's users; returns the dataset."""
    if dataset is None:
        dataset = prepare_demo(folder, url, windows=windows, overlap=overlap).dataset
    db = Database(url)
    try:
        add_tasks(db, dataset, overlap=overlap)
        with db.session() as session:
            base = list(session.scalars(select(Task).order_by(Task.id)))
            present = len(base)
            now = utcnow()
            for start in range(present, tasks, 2000):
                rows = [
                    {
                        "scenario_id": f"{base[n % len(base)].scenario_id}~{n}",
                        "agents": base[n % len(base)].agents,
                        "pair": base[n % len(base)].pair,
                        "pair_source": base[n % len(base)].pair_source,
                        "suggestions": base[n % len(base)].suggestions,
                        "overlap": overlap,
                        "quorum": overlap,
                        "created_at": now,
                    }
                    for n in range(start, min(tasks, start + 2000))
                ]
                ids = session.scalars(insert(Task).returning(Task.id), rows).all()
                session.execute(
                    insert(Slot),
                    [
                        {"task_id": t, "number": k, "state": SlotState.OPEN.value, "version": 0}
                        for t in ids
                        for k in range(overlap)
                    ],
                )
            for name in users:
                create_user(session, name, PASSWORD, Role.ANNOTATOR)
    finally:
        db.dispose()
    return dataset


def locked_slots(url: str) -> dict[int, tuple[int, int, float]]:
    """slot id -> (annotator id, version, lock expiry as epoch seconds) of every locked slot."""
    db = Database(url, upgrade=False)
    try:
        with db.session() as session:
            rows = session.execute(
                select(Slot.id, Slot.annotator_id, Slot.version, Slot.locked_until).where(
                    Slot.state == SlotState.LOCKED.value
                )
            ).all()
    finally:
        db.dispose()
    return {r.id: (r.annotator_id, r.version, epoch(r.locked_until)) for r in rows}


def slot_rows(url: str, ids: Sequence[int]) -> dict[int, tuple[str, int | None, int]]:
    """slot id -> (state, annotator id, version)."""
    db = Database(url, upgrade=False)
    try:
        with db.session() as session:
            rows = session.execute(
                select(Slot.id, Slot.state, Slot.annotator_id, Slot.version).where(Slot.id.in_(list(ids)))
            ).all()
    finally:
        db.dispose()
    return {r.id: (r.state, r.annotator_id, r.version) for r in rows}


def epoch(naive_utc: datetime) -> float:
    return naive_utc.replace(tzinfo=UTC).timestamp()


def parse_time(text: str) -> float:
    return datetime.fromisoformat(text.replace("Z", "+00:00")).timestamp()


# ---------------------------------------------------------------- the clients


@dataclass
class ClaimRecord:
    user: str
    slot_id: int
    task_id: int
    sent: float  # epoch seconds, client clock (the same machine as the server)
    answered: float
    locked_until: float
    ended: float = math.inf  # when its submit was answered (inf: never submitted, a ghost)


@dataclass
class Ack:
    user: str
    slot_id: int
    submission_id: str
    annotation_id: int
    pair: tuple[int, int]
    choices: tuple[tuple[int, int, str, str], ...]
    at: float


@dataclass
class Load:
    """What the clients share: the server's address, the gate closed while it is down, and the records."""

    base: str
    annotators: int
    max_submissions: int
    resend: float
    ghosts: tuple[str, ...] = ()
    up: asyncio.Event = field(default_factory=asyncio.Event)  # cleared while the server is down
    go: asyncio.Event = field(default_factory=asyncio.Event)  # set when the load begins
    logged_in: asyncio.Event = field(default_factory=asyncio.Event)
    ready: int = 0
    gave_up: list[str] = field(default_factory=list)
    cancelled: list[str] = field(default_factory=list)
    t0: float = 0.0
    stop_at: float = math.inf
    claims: list[ClaimRecord] = field(default_factory=list)
    acks: list[Ack] = field(default_factory=list)
    submit_ms: list[float] = field(default_factory=list)
    claim_ms: list[float] = field(default_factory=list)
    answers: Counter[str] = field(default_factory=Counter)  # "endpoint status" of every non-2xx answer
    connection_errors: Counter[str] = field(default_factory=Counter)
    resends: int = 0
    resends_bad: list[str] = field(default_factory=list)
    retried_submits: Counter[int] = field(default_factory=Counter)  # status after a retry across a lost connection
    lost_locks: int = 0  # submits answered 403/409: the slot was not the client's any more
    out_of_tasks: int = 0
    new_annotations: int = 0
    killed_at: float = math.inf
    restarted_at: float = math.inf
    fault: dict[str, Any] = field(default_factory=dict)
    aborted: bool = False  # the fault controller failed: the clients stop at once

    def stopping(self) -> bool:
        return time.time() >= self.stop_at or self.new_annotations >= self.max_submissions

    async def call(self, client: httpx.AsyncClient, path: str, **kwargs: Any) -> tuple[httpx.Response, int]:
        """POST `path`, retrying (the same body) after a lost connection once the server is up; returns the
        answer and how many connections were lost on the way."""
        lost = 0
        while True:
            await self.up.wait()
            try:
                return await client.post(path, **kwargs), lost
            except httpx.TransportError as exc:
                lost += 1
                self.connection_errors[f"{endpoint(path)} {type(exc).__name__}"] += 1
                if self.aborted or time.time() > self.stop_at + GRACE:
                    raise
                await asyncio.sleep(0.05)


def endpoint(path: str) -> str:
    return "submit" if path.endswith("/submit") else path.rsplit("/", 1)[-1]


def labels_for(task: dict[str, Any], rng: random.Random) -> tuple[tuple[int, int], list[dict[str, Any]]]:
    """A valid pair (the task's, else two of its agents) and random subtypes (half the time AGREE)."""
    pair = task["pair"]
    if len(pair) != 2:
        pair = rng.sample([a["id"] for a in task["agents"]], 2)
    a, b = int(pair[0]), int(pair[1])
    subtypes = AGREE if rng.random() < 0.5 else (rng.choice(SUBTYPES).id, rng.choice(SUBTYPES).id)
    choices = []
    for (track, other), subtype in zip(((a, b), (b, a)), subtypes, strict=True):
        text = f"load test {rng.randrange(10**6)}" if subtype == "other/undefined" else ""
        choices.append({"track_id": track, "other_id": other, "subtype": subtype, "text": text})
    return (a, b), choices


async def login(load: Load, client: httpx.AsyncClient, name: str) -> dict[str, str]:
    """Log in, count this client as ready (the last one to log in releases the start), and wait for the start;
    returns the CSRF header of every write."""
    r, _ = await load.call(client, "/api/login", json={"name": name, "password": PASSWORD})
    if r.status_code != 200:
        raise RuntimeError(f"login of {name} failed: {r.status_code} {r.text}")
    load.ready += 1
    if load.ready == load.annotators + len(load.ghosts):
        load.logged_in.set()
    await load.go.wait()
    return {"X-CSRF-Token": r.json()["csrf"]}


async def claim(load: Load, client: httpx.AsyncClient, name: str, headers: dict[str, str]) -> dict[str, Any] | None:
    """Claim the next task; its answer, or None after a non-2xx answer (counted)."""
    sent, t = time.time(), time.perf_counter()
    r, lost = await load.call(client, "/api/tasks/next", headers=headers)
    if r.status_code != 200:
        load.answers[f"next {r.status_code}"] += 1
        return None
    if not lost:
        load.claim_ms.append(1000 * (time.perf_counter() - t))
    body = r.json()
    if body["task"] is not None:
        body["record"] = ClaimRecord(
            name, body["slot_id"], body["task"]["task_id"], sent, time.time(), parse_time(body["locked_until"])
        )
        load.claims.append(body["record"])
    return body


async def annotator(load: Load, name: str, seed: int) -> None:
    try:
        await labeling(load, name, seed)
    except httpx.TransportError as exc:
        load.gave_up.append(f"{name}: {exc!r}")


async def labeling(load: Load, name: str, seed: int) -> None:
    rng = random.Random(seed)
    async with httpx.AsyncClient(base_url=load.base, timeout=REQUEST_TIMEOUT) as client:
        headers = await login(load, client, name)
        number = 0
        while not load.stopping():
            body = await claim(load, client, name, headers)
            if body is None:
                await asyncio.sleep(0.05)
                continue
            if body["task"] is None:
                load.out_of_tasks += 1
                return
            record: ClaimRecord = body["record"]
            pair, choices = labels_for(body["task"], rng)
            number += 1
            submission = {
                "submission_id": f"{name}-{number}-{secrets.token_hex(4)}",
                "pair": list(pair),
                "choices": choices,
                "lead_time_ms": rng.randrange(1000, 60000),
                "step_times_ms": {
                    "pair": rng.randrange(1000),
                    "type": rng.randrange(1000),
                    "subtype": rng.randrange(1000),
                },
            }
            path = f"/api/slots/{record.slot_id}/submit"
            t = time.perf_counter()
            r, lost = await load.call(client, path, json=submission, headers=headers)
            record.ended = time.time()
            if lost:
                load.retried_submits[r.status_code] += 1
            if r.status_code not in (200, 201):
                load.answers[f"submit {r.status_code}"] += 1
                if r.status_code in (403, 409):
                    load.lost_locks += 1
                continue
            if r.status_code == 200 and not lost:
                load.answers["submit 200 on a first attempt"] += 1  # a submission id seen before: a bug
            answer = r.json()
            if answer["created"]:
                load.new_annotations += 1
            if not lost:
                load.submit_ms.append(1000 * (time.perf_counter() - t))
            ack = Ack(
                name,
                record.slot_id,
                submission["submission_id"],
                int(answer["annotation_id"]),
                pair,
                tuple((c["track_id"], c["other_id"], c["subtype"], c["text"]) for c in choices),
                time.time(),
            )
            load.acks.append(ack)
            if rng.random() < load.resend:
                load.resends += 1
                again, _ = await load.call(client, path, json=submission, headers=headers)
                if again.status_code != 200 or again.json() != {"annotation_id": ack.annotation_id, "created": False}:
                    load.resends_bad.append(f"{submission['submission_id']}: {again.status_code} {again.text}")


async def ghost(load: Load, name: str, claim_at: float) -> None:
    """Log in (before the load), claim a slot at `claim_at` and vanish: its lock must expire and the slot go
    back to the queue."""
    async with httpx.AsyncClient(base_url=load.base, timeout=REQUEST_TIMEOUT) as client:
        headers = await login(load, client, name)
        await sleep_until(load.t0 + claim_at)
        body = await claim(load, client, name, headers)
        if body is None or body["task"] is None:
            raise RuntimeError(f"ghost {name} could not claim a slot: {body}")


async def sleep_until(t: float) -> None:
    await asyncio.sleep(max(0.0, t - time.time()))


async def faults(load: Load, server: Server, url: str, kill_at: float, ghosts: Sequence[asyncio.Task[None]]) -> None:
    """The ghosts' claims, the kill, the wait for the ghosts' locks to expire, the restart and the checks of
    the slots' states right after it (the clients are held back until then)."""
    try:
        await crash(load, server, url, kill_at, ghosts)
    except BaseException:
        load.aborted, load.stop_at = True, time.time()
        load.up.set()
        raise


async def crash(load: Load, server: Server, url: str, kill_at: float, ghosts: Sequence[asyncio.Task[None]]) -> None:
    await asyncio.gather(*ghosts)
    ghost_claims = [c for c in load.claims if c.user in load.ghosts]
    await sleep_until(load.t0 + kill_at)
    load.up.clear()
    server.kill()
    load.killed_at = time.time()
    held = await asyncio.to_thread(locked_slots, url)
    await sleep_until(max(load.killed_at + load.fault["down_seconds"], *(c.locked_until + 0.5 for c in ghost_claims)))
    load.restarted_at = time.time()
    load.fault["restart_s"] = await asyncio.to_thread(server.start)
    ready = time.time()
    after = await asyncio.to_thread(slot_rows, url, list(held))
    expired = [s for s, (_, _, until) in held.items() if until < load.restarted_at]
    live = [s for s, (_, _, until) in held.items() if until > ready + 0.5]
    load.fault.update(
        held_at_kill=len(held),
        ghost_slots=[c.slot_id for c in ghost_claims],
        expired=len(expired),
        expired_not_open=[s for s in expired if after[s][0] != SlotState.OPEN.value or after[s][1] is not None],
        live=len(live),
        live_not_kept=[s for s in live if after[s] != (SlotState.LOCKED.value, held[s][0], held[s][1])],
        downtime_s=ready - load.killed_at,
    )
    load.stop_at = max(load.stop_at, time.time() + AFTER_RESTART)
    load.up.set()


async def drive(args: argparse.Namespace, server: Server, url: str, names: Sequence[str], ghosts: Sequence[str]):
    load = Load(server.base, len(names), args.max_submissions, args.resend, tuple(ghosts))
    load.fault["down_seconds"] = args.down_seconds
    load.up.set()
    clients = [asyncio.create_task(annotator(load, n, args.seed * 100003 + i)) for i, n in enumerate(names)]
    claim_at = max(0.0, args.kill_at - 60 * args.lock_minutes + GHOST_EXPIRY_AFTER_KILL)
    vanishing = [asyncio.create_task(ghost(load, g, claim_at)) for g in ghosts]
    logged_in = asyncio.create_task(load.logged_in.wait())
    await asyncio.wait([logged_in, *clients, *vanishing], return_when=asyncio.FIRST_COMPLETED)  # Argon2: not timed
    if not logged_in.done():
        for task in [*clients, *vanishing]:
            if task.done():
                task.result()  # a client failed before the load began: raise its error
    load.t0 = time.time()
    load.stop_at = load.t0 + args.seconds
    load.go.set()
    controller = asyncio.create_task(faults(load, server, url, args.kill_at, vanishing)) if vanishing else None
    finished, pending = await asyncio.wait(clients, timeout=args.seconds + GRACE + MAX_DOWNTIME)
    for task in pending:
        task.cancel()
    load.cancelled = [names[clients.index(task)] for task in pending]
    wall = time.time() - load.t0
    if controller is not None:
        await controller
    for task in finished:
        task.result()
    return load, wall


# ---------------------------------------------------------------- the checks


@dataclass(frozen=True)
class Check:
    name: str
    passed: bool
    detail: str


def check_database(url: str, load: Load, names: Sequence[str], overlap: int) -> list[Check]:
    """What the database holds against what the clients were told."""
    db = Database(url, upgrade=False)
    try:
        with db.session() as session:
            users = dict(session.execute(select(User.name, User.id)).all())
            by_id = {u: n for n, u in users.items()}
            annotations = {a.id: a for a in session.scalars(select(Annotation))}
            choices = {
                a.id: sorted((c.track_id, c.other_id, c.subtype, c.text) for c in a.choices)
                for a in annotations.values()
            }
    finally:
        db.dispose()
    checks = []
    missing, wrong = [], []
    for ack in load.acks:
        a = annotations.get(ack.annotation_id)
        if a is None:
            missing.append(ack.submission_id)
        elif (
            a.submission_id != ack.submission_id
            or by_id.get(a.annotator_id) != ack.user
            or a.slot_id != ack.slot_id
            or (a.agent_a, a.agent_b) != ack.pair
            or choices[a.id] != sorted(ack.choices)
        ):
            wrong.append(ack.submission_id)
    before = sum(ack.at < load.killed_at for ack in load.acks)
    checks.append(
        Check(
            "no acknowledged label lost",
            bool(load.acks) and not missing and not wrong,
            f"{len(load.acks)} acknowledged ({before} before the kill): {len(missing)} missing, "
            f"{len(wrong)} stored with other labels/slot/annotator"
            + (f", e.g. {(missing + wrong)[0]}" if missing or wrong else ""),
        )
    )
    load_users = {users[n] for n in names}
    ours = [a for a in annotations.values() if a.annotator_id in load_users]
    per_slot = Counter(a.slot_id for a in annotations.values())
    per_task_user = Counter((a.task_id, a.annotator_id) for a in annotations.values())
    per_task = Counter(a.task_id for a in annotations.values())
    acked = {ack.submission_id for ack in load.acks}
    unacked = [a.submission_id for a in ours if a.submission_id not in acked]
    problems = {
        "slots with two annotations": sum(n > 1 for n in per_slot.values()),
        "annotators with two annotations of a task": sum(n > 1 for n in per_task_user.values()),
        f"tasks with more than {overlap} annotations": sum(n > overlap for n in per_task.values()),
        "annotations nobody was told of": len(unacked),
        "submission ids acknowledged twice": len(load.acks) - len(acked),
        "resends not answered with the first copy": len(load.resends_bad),
        "first submits answered 200": load.answers["submit 200 on a first attempt"],
    }
    bad = {k: v for k, v in problems.items() if v}
    checks.append(
        Check(
            "no duplicate label",
            not bad,
            f"{len(ours)} annotations of the load's annotators, {len(acked)} distinct acknowledged, "
            f"{load.resends} resends deduplicated"
            + (f"; {bad}" if bad else "")
            + (f"; e.g. {load.resends_bad[0]}" if load.resends_bad else ""),
        )
    )
    checks.append(held_twice(load.claims))
    expected = {"submit 403", "submit 409", "next 409"}  # a lock lost once it expired; contention, retried
    unexpected = {k: v for k, v in load.answers.items() if k not in expected and v}
    checks.append(
        Check("no 5xx or unexpected answer", not unexpected, f"{unexpected or 'none'} (allowed: {sorted(expected)})")
    )
    unfinished = load.gave_up + [f"{n} cancelled" for n in load.cancelled]
    checks.append(
        Check(
            "every client finished",
            not unfinished,
            f"{len(names)} clients; gave up or cancelled: {unfinished or 'none'}",
        )
    )
    return checks


def held_twice(claims: Sequence[ClaimRecord]) -> Check:
    """No two annotators held one slot at once: for claims of a slot by different users, ordered by when
    they were answered, the later one must come after the earlier one ended or after its lock expired."""
    by_slot: dict[int, list[ClaimRecord]] = defaultdict(list)
    for c in claims:
        by_slot[c.slot_id].append(c)
    overlaps, after_expiry = [], 0
    for slot, held in by_slot.items():
        held.sort(key=lambda c: c.answered)
        for i, first in enumerate(held):
            for second in held[i + 1 :]:
                if second.user == first.user or second.sent >= first.ended:
                    continue
                if second.answered >= first.locked_until:
                    after_expiry += 1  # granted (at the latest when answered) once the first lock had expired
                    continue
                overlaps.append(f"slot {slot}: {first.user} and {second.user}")
    shared = sum(len({c.user for c in held}) > 1 for held in by_slot.values())
    return Check(
        "no slot held twice",
        not overlaps,
        f"{len(claims)} claims of {len(by_slot)} slots; {shared} slots claimed by more than one annotator "
        f"({after_expiry} takeovers after a lock expired); {len(overlaps)} overlapping holds"
        + (f", e.g. {overlaps[0]}" if overlaps else ""),
    )


def check_faults(url: str, load: Load) -> list[Check]:
    f = load.fault
    ghost_slots = f["ghost_slots"]
    after = slot_rows(url, ghost_slots)
    reclaimed = [
        s
        for s in ghost_slots
        if any(c.slot_id == s and c.user not in load.ghosts and c.answered > load.restarted_at for c in load.claims)
    ]
    return [
        Check(
            "expired locks open after the restart",
            f["expired"] >= len(ghost_slots) > 0 and not f["expired_not_open"],
            f"{f['held_at_kill']} slots locked at the kill, {f['expired']} expired before the restart "
            f"({len(ghost_slots)} ghosts'); not open: {f['expired_not_open'] or 'none'}",
        ),
        Check(
            "unexpired locks kept by their annotators",
            not f["live_not_kept"],
            f"{f['live']} unexpired at the restart; not kept: {f['live_not_kept'] or 'none'}",
        ),
        Check(
            "released slots claimed again by others",
            len(reclaimed) == len(ghost_slots),
            f"{len(reclaimed)} of {len(ghost_slots)} ghost slots claimed after the restart "
            f"(now {sorted(Counter(state for state, _, _ in after.values()).items())})",
        ),
    ]


# ---------------------------------------------------------------- one backend


@dataclass
class Result:
    backend: str
    checks: list[Check]
    figures: dict[str, Any]

    @property
    def passed(self) -> bool:
        return all(c.passed for c in self.checks)


def percentiles(values: Sequence[float]) -> tuple[float, float]:
    if not values:
        return math.nan, math.nan
    p50, p95 = np.percentile(np.asarray(values), [50, 95])
    return float(p50), float(p95)


def run_backend(backend: str, url: str, folder: Path, args: argparse.Namespace) -> Result:
    names = [f"load{n:03d}" for n in range(1, args.annotators + 1)]
    ghosts = [f"ghost{n:02d}" for n in range(1, args.ghosts + 1)] if args.kill_at > 0 else []
    tasks = math.ceil(args.max_submissions / args.overlap) + len(names) + len(ghosts)
    t = time.perf_counter()
    dataset = prepare(folder, url, args.windows, tasks, args.overlap, [*names, *ghosts], args.dataset)
    prepared = time.perf_counter() - t
    server = Server(dataset, url, args.lock_minutes, folder / f"server-{backend}.log")
    started = server.start()
    try:
        load, wall = asyncio.run(drive(args, server, url, names, ghosts))
    finally:
        server.stop()
    checks = check_database(url, load, names, args.overlap)
    if ghosts:
        checks += check_faults(url, load)
    p50, p95 = percentiles(load.submit_ms)
    c50, c95 = percentiles(load.claim_ms)
    figures = {
        "tasks": tasks,
        "prepare_s": prepared,
        "server_start_s": started,
        "wall_s": wall,
        "submit_p50_ms": p50,
        "submit_p95_ms": p95,
        "claim_p50_ms": c50,
        "claim_p95_ms": c95,
        "submissions_per_s": load.new_annotations / wall,
        "new_annotations": load.new_annotations,
        "acknowledged": len(load.acks),
        "claims": len(load.claims),
        "resends": load.resends,
        "lost_locks": load.lost_locks,
        "out_of_tasks": load.out_of_tasks,
        "capped": load.new_annotations >= args.max_submissions,
        "answers": dict(load.answers),
        "connection_errors": dict(load.connection_errors),
        "retried_submits": dict(load.retried_submits),
        "fault": {k: v for k, v in load.fault.items() if not isinstance(v, list)},
    }
    if any(not c.passed for c in checks):
        figures["server_log_tail"] = server.log_tail()
    return Result(backend, checks, figures)


def report(result: Result, args: argparse.Namespace) -> None:
    f = result.figures
    kill = f", SIGKILL at {args.kill_at:g} s" if args.kill_at > 0 else ""
    print(
        f"\n== {result.backend}: {args.annotators} annotators, {args.seconds:g} s, overlap {args.overlap}, "
        f"locks {60 * args.lock_minutes:g} s{kill}"
    )
    print(f"prepared {f['tasks']} tasks in {f['prepare_s']:.1f} s; server up in {f['server_start_s']:.1f} s")
    print(f"submit latency  p50 {f['submit_p50_ms']:.1f} ms  p95 {f['submit_p95_ms']:.1f} ms")
    print(f"claim latency   p50 {f['claim_p50_ms']:.1f} ms  p95 {f['claim_p95_ms']:.1f} ms")
    print(
        f"submissions     {f['new_annotations']} new in {f['wall_s']:.1f} s = {f['submissions_per_s']:.1f}/s"
        + (" (stopped at --max-submissions)" if f["capped"] else "")
    )
    print(
        f"claims {f['claims']}, acknowledged {f['acknowledged']} (with {f['resends']} resends), "
        f"locks lost {f['lost_locks']}, clients out of tasks {f['out_of_tasks']}"
    )
    print(f"non-2xx answers {f['answers'] or 'none'}; lost connections {f['connection_errors'] or 'none'}")
    if args.kill_at > 0:
        fault = f["fault"]
        print(
            f"kill: down {fault.get('downtime_s', math.nan):.1f} s (restart {fault.get('restart_s', math.nan):.1f} s); "
            f"submits retried across it, by final status: {f['retried_submits'] or 'none'}"
        )
    for c in result.checks:
        print(f"{'PASS' if c.passed else 'FAIL'}  {c.name}: {c.detail}")
    if not result.passed and "server_log_tail" in f:
        print("server log (tail):\n" + f["server_log_tail"])


# ---------------------------------------------------------------- main


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--backend", choices=("sqlite", "postgresql", "both"), default="both")
    p.add_argument("--annotators", type=int, default=50)
    p.add_argument("--seconds", type=float, default=120.0, help="wall time of the load, the downtime included")
    p.add_argument("--kill-at", type=float, default=60.0, help="SIGKILL the server this far into the load (0: never)")
    p.add_argument("--down-seconds", type=float, default=1.0, help="least time the server stays down")
    p.add_argument("--lock-minutes", type=float, default=0.25, help="the server's lock (default 15 s)")
    p.add_argument("--ghosts", type=int, default=5, help="annotators who claim a slot and vanish before the kill")
    p.add_argument("--overlap", type=int, default=2)
    p.add_argument("--windows", type=int, default=4, help="SUMO windows synthesized; the other tasks copy them")
    p.add_argument("--dataset", type=Path, help="take the windows of this InterDrive dataset instead (not modified)")
    p.add_argument("--max-submissions", type=int, default=20000, help="hard cap on acknowledged new submits")
    p.add_argument("--resend", type=float, default=0.02, help="share of acknowledged submits sent again")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--keep", type=Path, help="work in this folder and keep it (default: a temporary one)")
    args = p.parse_args(argv)
    if args.annotators < 1 or args.seconds <= 0 or args.max_submissions < 1 or args.overlap < 1:
        p.error("--annotators, --seconds, --max-submissions and --overlap must be positive")
    if args.kill_at > 0:
        if args.kill_at >= args.seconds:
            p.error("--kill-at must fall inside the load (< --seconds)")
        if args.ghosts < 1:
            p.error("the kill needs at least one ghost (--ghosts) to check that expired locks are released")
        if 60 * args.lock_minutes - args.kill_at > MAX_DOWNTIME - GHOST_EXPIRY_AFTER_KILL:
            p.error(f"--lock-minutes {args.lock_minutes:g} is too long for --kill-at {args.kill_at:g}: the ghosts' "
                    f"locks must expire within {MAX_DOWNTIME:g} s of the kill")  # fmt: skip
    return args


def benchmark(argv: Sequence[str] | None = None) -> list[Result]:
    """Run the load on the chosen backends; a backend that cannot run is skipped with the reason printed."""
    args = parse_args(argv)
    print(f"{platform.node()}: {os.cpu_count()} cores, Python {platform.python_version()}, {datetime.now():%Y-%m-%d}, "
          f"load average {os.getloadavg()[0]:.1f} before")  # fmt: skip
    results = []
    with tempfile.TemporaryDirectory(prefix="label-load-") as tmp:
        root = args.keep or Path(tmp)
        if args.backend in ("sqlite", "both"):
            folder = root / "sqlite"
            results.append(run_backend("sqlite", f"sqlite:///{folder.resolve() / 'labeling.sqlite'}", folder, args))
            report(results[-1], args)
        if args.backend in ("postgresql", "both"):
            from langtraj.labeling.devdb import PostgresUnavailable, TemporaryPostgres

            try:
                server = TemporaryPostgres()
            except PostgresUnavailable as exc:
                print(f"\n== postgresql: skipped ({exc})")
            else:
                with server:
                    url = server.create_database("label_load")
                    results.append(run_backend("postgresql", url, root / "postgresql", args))
                report(results[-1], args)
    return results


def main(argv: Sequence[str] | None = None) -> int:
    results = benchmark(argv)
    failed = [r.backend for r in results if not r.passed]
    print(f"\n{'FAIL on ' + ', '.join(failed) if failed else 'all checks passed'}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
