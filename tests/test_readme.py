"""The README's two commands are the ones CI runs."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _ci_command(name: str) -> str:
    match = re.search(rf"^{name}='(.+)'$", (ROOT / ".ci" / "run").read_text(), re.MULTILINE)
    assert match, f"{name}= not found in .ci/run"
    return match.group(1)


def test_readme_quotes_the_ci_commands_verbatim() -> None:
    blocks = re.findall(r"```\n(.+?)\n```", (ROOT / "README.md").read_text(), re.DOTALL)
    assert blocks[:2] == [_ci_command("INSTALL_AND_RUN"), _ci_command("TEST")]
