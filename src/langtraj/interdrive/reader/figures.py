"""How well the prompt reader reads prompts of known kinds: `ReadingFigures` (right, misread, unread),
`reading_figures` over (text, kind, agent, other) rows, `file_figures` over a free-text prompt file, and `main`, the
command line `python -m langtraj.interdrive.reader FILE...` (run by `__main__.py`) that prints them.

See docs/interdrive.md ('Reading a prompt').
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from langtraj.errors import InputError
from langtraj.interdrive.behaviour import BEHAVIOURS, Behaviour
from langtraj.interdrive.free_text import load_free_text_prompts
from langtraj.interdrive.reader.read import PromptReading, read_prompt

# ---------------------------------------------------------------------------------------------- figures


@dataclass(frozen=True)
class ReadingFigures:
    """How a set of prompts with known kinds reads: `right` as its kind, `misread` as another, `unread` as none."""

    total: int
    right: int
    misread: tuple[tuple[str, PromptReading], ...]
    unread: tuple[tuple[str, PromptReading], ...]

    @property
    def share_right(self) -> float:
        return self.right / self.total if self.total else 0.0

    def summary(self) -> str:
        return (
            f"{self.total} prompts: {self.right} read right ({100 * self.share_right:.1f} %), "
            f"{len(self.misread)} misread (another behaviour or agent), {len(self.unread)} unread"
        )


def reading_figures(prompts: Iterable[tuple[str, Behaviour, int, int | None]]) -> ReadingFigures:
    """Read each (text, kind asked, agent, other) and count the right, misread and unread ones."""
    total = right = 0
    misread: list[tuple[str, PromptReading]] = []
    unread: list[tuple[str, PromptReading]] = []
    for text, behaviour, agent, other in prompts:
        total += 1
        reading = read_prompt(text)
        if reading.behaviour is None:
            unread.append((text, reading))
        elif (reading.behaviour, reading.agent, reading.other) == (behaviour, agent, other):
            right += 1
        else:
            misread.append((text, reading))
    return ReadingFigures(total, right, tuple(misread), tuple(unread))


def file_figures(path: str, agent: int = 12, other: int = 7) -> ReadingFigures:
    """`reading_figures` of a free-text prompt file (`free_text.load_free_text_prompts`), rendered for
    `agent` (and `other` for pair kinds)."""
    rendered = []
    for prompt in load_free_text_prompts(path):
        pair = BEHAVIOURS[prompt.behaviour].is_pair
        rendered.append((prompt.render(agent, other), prompt.behaviour, agent, other if pair else None))
    return reading_figures(rendered)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m langtraj.interdrive.reader",
        description="Read free-text prompt files ({text, behaviour} entries) and print how many read right.",
    )
    parser.add_argument("files", nargs="+", metavar="FILE")
    parser.add_argument("-v", "--verbose", action="store_true", help="list the misread and unread prompts")
    args = parser.parse_args(argv)
    for path in args.files:
        try:
            figures = file_figures(path)
        except InputError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
        print(f"{path}: {figures.summary()}")
        if args.verbose:
            for label, rows in (("misread", figures.misread), ("unread", figures.unread)):
                for prompt_text, reading in rows:
                    print(f"  {label}: {prompt_text!r} -> {reading.describe()}")
    return 0
