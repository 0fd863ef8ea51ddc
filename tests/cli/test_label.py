"""`langtraj label ...`: users from standard input, tasks, progress, export, the demo, and one-line errors."""

from __future__ import annotations

import io
import json
from pathlib import Path

import pytest
from labeling.builders import labels_body, make_label_dataset

from langtraj.cli.main import main
from langtraj.labeling import tasks
from langtraj.labeling.auth import Identity, authenticate
from langtraj.labeling.db import Database, default_url
from langtraj.labeling.models import Role
from langtraj.labeling.protocol import parse_labels


def run(monkeypatch: pytest.MonkeyPatch, *argv: str, stdin: str = "") -> int:
    monkeypatch.setattr("sys.stdin", io.StringIO(stdin))
    return main(["label", *argv])


def test_users_tasks_progress_and_export(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys) -> None:  # type: ignore[no-untyped-def]
    dataset = make_label_dataset(tmp_path, num_scenes=2)
    assert run(monkeypatch, "user", str(dataset), "alice", "--role", "annotator", stdin="s3cret-password\n") == 0
    assert run(monkeypatch, "user", str(dataset), "bob", stdin="another-password\n") == 0
    assert run(monkeypatch, "tasks", str(dataset), "--overlap", "1") == 0
    assert "added 2 tasks" in capsys.readouterr().out
    db = Database(default_url(dataset))
    with db.session() as session:
        alice = authenticate(session, "alice", "s3cret-password")
        assert alice is not None and authenticate(session, "alice", "wrong-password") is None
    who = Identity(alice.id, "alice", Role.ANNOTATOR, "")
    body = labels_body()
    for n in range(2):
        claim = tasks.claim_next(db, who)
        tasks.submit(db, who, claim.slot_id, f"cli-sub-{n}", parse_labels(body["pair"], body["choices"]), 5, {})
    db.dispose()
    assert run(monkeypatch, "progress", str(dataset)) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["progress"]["per_annotator"] == {"alice": 2} and report["progress"]["tasks_accepted"] == 2
    out = tmp_path / "export"
    assert run(monkeypatch, "export", str(dataset), "--out", str(out / "json"), "--into") == 0
    assert "wrote 2 InterDrive files" in capsys.readouterr().out
    assert sorted(p.name for p in (out / "json").iterdir()) == ["win-0.json", "win-1.json"]
    assert json.loads((out / "labeling-audit.json").read_text())["windows"][0]["annotations"][0]["annotator"] == "alice"


@pytest.mark.parametrize(
    ("argv", "stdin", "message"),
    [
        (["user", "{ds}", "carol"], "short\n", "password must have at least 8 characters"),
        (["user", "{ds}", "carol", "--role", "king"], "long-enough-pw\n", "unknown role 'king'"),
        (["user", "{ds}", "a b"], "long-enough-pw\n", "user name 'a b'"),
        (["tasks", "{ds}", "--scenario", "win-0", "nope"], "", "no window 'nope'"),
        (["tasks", "{ds}", "--overlap", "0"], "", "--overlap"),
        (["tasks", "{tmp}"], "", "not an InterDrive dataset folder"),
        (["serve", "{tmp}"], "", "not an InterDrive dataset folder"),
        (["tasks", "{ds}", "--db", "mysql://x/y"], "", "unsupported database 'mysql'"),
        (["tasks", "{ds}", "--db", "sqlite://"], "", "SQLite needs a file"),
        (["tasks", "{ds}", "--db", "::not a url::"], "", "not a database URL"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(tmp_path: Path, monkeypatch, capsys, argv, stdin, message) -> None:  # type: ignore[no-untyped-def]
    dataset = make_label_dataset(tmp_path, num_scenes=1)
    argv = [a.format(ds=dataset, tmp=tmp_path) for a in argv]
    assert run(monkeypatch, *argv, stdin=stdin) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err, err


def test_a_taken_user_name_is_refused(tmp_path: Path, monkeypatch, capsys) -> None:  # type: ignore[no-untyped-def]
    dataset = make_label_dataset(tmp_path, num_scenes=1)
    assert run(monkeypatch, "user", str(dataset), "dora", stdin="long-enough-pw\n") == 0
    assert run(monkeypatch, "user", str(dataset), "dora", stdin="long-enough-pw\n") == 2
    assert "user 'dora' exists already" in capsys.readouterr().err


def test_demo_prepares_a_dataset_and_prints_passwords_that_work(tmp_path: Path, monkeypatch, capsys) -> None:  # type: ignore[no-untyped-def]
    assert run(monkeypatch, "demo", "--out", str(tmp_path / "demo"), "--windows", "2", "--no-serve") == 0
    out = capsys.readouterr().out
    passwords = dict(line.split()[1::2] for line in out.splitlines() if line.strip().startswith("user "))
    assert set(passwords) == {"admin", "reviewer", "annotator1", "annotator2"}
    dataset = tmp_path / "demo" / "dataset"
    db = Database(default_url(dataset))
    with db.session() as session:
        assert authenticate(session, "admin", passwords["admin"]).role == "admin"  # type: ignore[union-attr]
    assert tasks.progress(db)["tasks"] >= 2
    db.dispose()
    assert run(monkeypatch, "demo", "--out", str(tmp_path / "demo"), "--windows", "2", "--no-serve") == 0
    assert "exist already" in capsys.readouterr().out
