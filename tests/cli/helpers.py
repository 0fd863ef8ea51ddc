"""What the command tests share: running `main` with captured output, the one-line error check, and the
metadata of a WOSAC submission."""

from __future__ import annotations

import pytest

from langtraj.cli.main import main

METADATA = {
    "account_name": "someone@example.com",
    "unique_method_name": "langtraj-test",
    "authors": ["A. Person"],
    "affiliation": "Nowhere",
    "description": "constant velocity",
    "method_link": "https://example.com",
    "num_model_parameters": "0",
    "acknowledge_complies_with_closed_loop_requirement": True,
}


def run_cli(args: list[str], capsys: pytest.CaptureFixture) -> tuple[int, str, str]:
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


def assert_one_line_error(code: int, err: str, *needles: str) -> None:
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert "Traceback" not in err
    for needle in needles:
        assert needle in lines[0], lines[0]
