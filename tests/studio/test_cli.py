"""`langtraj studio`: the default address, the warning for any other, and bad options."""

from __future__ import annotations

from pathlib import Path

import pytest

from langtraj.cli.main import main


@pytest.fixture
def served(monkeypatch: pytest.MonkeyPatch) -> list[dict]:
    import uvicorn

    calls: list[dict] = []
    monkeypatch.setattr(uvicorn, "run", lambda app, **kw: calls.append({"app": app, **kw}))
    return calls


def test_serves_on_localhost_without_a_warning(served, real_data_dir: Path, tmp_path: Path, capsys) -> None:
    womd = real_data_dir / "motion_data_one_scenario.tfrecord"
    assert main(["studio", str(womd), "--data", str(tmp_path), "--port", "8123"]) == 0
    (call,) = served
    assert (call["host"], call["port"]) == ("127.0.0.1", 8123)
    out = capsys.readouterr()
    assert "1 scenes" in out.out and out.err == ""
    call["app"].state.board.close()


def test_any_other_host_warns_that_there_are_no_accounts(served, real_data_dir: Path, tmp_path: Path, capsys) -> None:
    womd = real_data_dir / "motion_data_one_scenario.tfrecord"
    assert main(["studio", str(womd), "--data", str(tmp_path), "--host", "0.0.0.0"]) == 0
    assert "no accounts" in capsys.readouterr().err
    served[0]["app"].state.board.close()


def test_bad_options(served, tmp_path: Path, capsys) -> None:
    assert main(["studio", "--checkpoint", str(tmp_path / "none.ckpt")]) == 2
    assert "none.ckpt" in capsys.readouterr().err and not served
