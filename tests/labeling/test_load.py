"""The load and crash benchmark (benchmarks/label_load.py) in small: the real server as a subprocess,
concurrent annotators over HTTP, a SIGKILL in the middle and a restart, then the database checked against
every acknowledged submit. The fast test keeps the crash guarantees in every CI run; the benchmark's
checkers are also shown to fail on a lost label, an unacknowledged copy and a slot held twice."""

from __future__ import annotations

import importlib.util
import math
import sys
from pathlib import Path

import pytest
from builders import add_user, make_label_dataset

from langtraj.labeling.db import Database, default_url
from langtraj.labeling.models import Annotation, Choice, SlotState, Task
from langtraj.labeling.tasks import add_tasks

ROOT = Path(__file__).resolve().parents[2]


def _load_benchmark():  # type: ignore[no-untyped-def]
    spec = importlib.util.spec_from_file_location("label_load", ROOT / "benchmarks" / "label_load.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["label_load"] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


label_load = _load_benchmark()


def _assert_passed(results, kill: bool) -> None:  # type: ignore[no-untyped-def]
    for result in results:
        failed = [f"{c.name}: {c.detail}" for c in result.checks if not c.passed]
        assert not failed, f"{result.backend}: {failed}\n{result.figures.get('server_log_tail', '')}"
        names = {c.name for c in result.checks}
        assert "no acknowledged label lost" in names and "no slot held twice" in names
        assert result.figures["new_annotations"] > 0
        if kill:
            assert "expired locks open after the restart" in names
            assert result.figures["fault"]["downtime_s"] > 0  # the server was down and came back
            assert result.figures["fault"]["expired"] >= 1


# Locks of 6 s: the ghosts claim at the start and their locks expire while the server is down (killed at
# 5 s, restarted once they expired); the live annotators' locks, taken just before the kill, outlast the
# restart unless the machine is slow. The load goes on for label_load.AFTER_RESTART s after the restart.
FAST = "--backend sqlite --annotators 5 --seconds 6 --kill-at 5 --lock-minutes 0.1 --ghosts 2 --max-submissions 1000"


def test_load_with_a_kill_loses_no_acknowledged_label_sqlite(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    results = label_load.benchmark([*FAST.split(), "--dataset", str(make_label_dataset(tmp_path))])
    print(capsys.readouterr().out)
    assert [r.backend for r in results] == ["sqlite"]
    _assert_passed(results, kill=True)


@pytest.mark.slow
def test_load_with_a_kill_sqlite_longer() -> None:
    args = "--backend sqlite --annotators 10 --seconds 10 --kill-at 5 --lock-minutes 0.1 --ghosts 3"
    assert label_load.main([*args.split(), "--max-submissions", "3000"]) == 0


@pytest.mark.slow
def test_load_with_a_kill_postgresql(postgres_url: str, tmp_path: Path) -> None:
    argv = "--backend postgresql --annotators 10 --seconds 10 --kill-at 5 --lock-minutes 0.1 --ghosts 3"
    args = label_load.parse_args([*argv.split(), "--max-submissions", "3000"])
    result = label_load.run_backend("postgresql", postgres_url, tmp_path, args)
    label_load.report(result, args)
    _assert_passed([result], kill=True)


# ---------------------------------------------------------------- the checkers can fail


def _ack(user: str, slot: int, submission: str, annotation: int):  # type: ignore[no-untyped-def]
    choices = ((7, 17, "other/no_interaction", ""), (17, 7, "other/no_interaction", ""))
    return label_load.Ack(user, slot, submission, annotation, (7, 17), choices, 1.0)


def _annotate(db: Database, task_id: int, slot_number: int, user_id: int, submission: str) -> int:
    with db.session() as session:
        task = session.get(Task, task_id)
        assert task is not None
        slot = task.slots[slot_number]
        slot.state, slot.annotator_id = SlotState.DONE.value, user_id
        row = Annotation(
            submission_id=submission, slot_id=slot.id, task_id=task_id, annotator_id=user_id, agent_a=7, agent_b=17,
            lead_time_ms=1, step_times_ms={}, submitted_at=task.created_at,
            choices=[Choice(track_id=7, other_id=17, subtype="other/no_interaction", text=""),
                     Choice(track_id=17, other_id=7, subtype="other/no_interaction", text="")],
        )  # fmt: skip
        session.add(row)
        session.flush()
        return row.id


def test_database_checks_fail_on_a_lost_or_unacknowledged_label(tmp_path: Path) -> None:
    dataset = make_label_dataset(tmp_path)
    url = default_url(dataset)
    db = Database(url)
    add_tasks(db, dataset, overlap=2)
    user = add_user(db, "load001")
    kept = _annotate(db, 1, 0, user.id, "sub-kept-0001")
    db.dispose()

    load = label_load.Load("http://unused", 1, 100, 0.0)
    load.acks = [_ack("load001", 1, "sub-kept-0001", kept)]
    checks = {c.name: c for c in label_load.check_database(url, load, ["load001"], 2)}
    assert checks["no acknowledged label lost"].passed and checks["no duplicate label"].passed

    load.acks.append(_ack("load001", 3, "sub-lost-0001", kept + 100))  # acknowledged, not in the database
    checks = {c.name: c for c in label_load.check_database(url, load, ["load001"], 2)}
    assert not checks["no acknowledged label lost"].passed
    assert "1 missing" in checks["no acknowledged label lost"].detail

    load.acks = [_ack("load001", 1, "sub-kept-0001", kept)]
    db = Database(url)
    _annotate(db, 2, 0, user.id, "sub-silent-001")  # written, never acknowledged
    db.dispose()
    checks = {c.name: c for c in label_load.check_database(url, load, ["load001"], 2)}
    assert not checks["no duplicate label"].passed
    assert "annotations nobody was told of" in checks["no duplicate label"].detail

    load.acks = [_ack("load001", 1, "sub-kept-0001", kept), _ack("load001", 2, "sub-wrong-001", kept)]
    checks = {c.name: c for c in label_load.check_database(url, load, ["load001"], 2)}
    assert not checks["no acknowledged label lost"].passed  # the id answered belongs to another submission


def test_held_twice_fails_on_overlapping_holds_and_allows_takeover_after_expiry() -> None:
    claim = label_load.ClaimRecord
    first = claim("a", 5, 1, sent=0.0, answered=0.1, locked_until=10.0, ended=3.0)
    assert label_load.held_twice([first, claim("b", 5, 1, 3.5, 3.6, 13.6, 4.0)]).passed  # after a's submit
    assert label_load.held_twice([first, claim("a", 5, 1, 1.0, 1.1, 11.1, 2.0)]).passed  # a again: its own
    overlap = label_load.held_twice([first, claim("b", 5, 1, 1.0, 1.1, 11.1, 2.0)])
    assert not overlap.passed and "slot 5: a and b" in overlap.detail
    ghost = claim("g", 6, 2, 0.0, 0.1, 5.0, math.inf)  # never submitted
    assert label_load.held_twice([ghost, claim("b", 6, 2, 4.9, 5.2, 15.2, 6.0)]).passed  # granted after expiry
    assert not label_load.held_twice([ghost, claim("b", 6, 2, 4.0, 4.5, 14.5, 6.0)]).passed  # before it
