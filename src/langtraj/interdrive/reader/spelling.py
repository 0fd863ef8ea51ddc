"""Near-misses of the reader's words: a clause the reader cannot read because a word is misspelt ("yeilds", "trun")
gets a "did you mean" instead of steering by its text alone; only where the clause with the word corrected reads,
so that a word the reader never knew ("honks") is not taken for a typo (docs/interdrive.md, 'Reading a prompt')."""

from __future__ import annotations

import difflib
import re
from functools import cache

from langtraj.interdrive.reader.read import read_prompt
from langtraj.interdrive.reader.rules import tables

MIN_LETTERS = 4
"""Words shorter than this are never corrected ("at", "to", "the" are too close to too much)."""
CUTOFF = 0.75
"""`difflib` similarity a word needs to a reader word to count as its misspelling ("trun" / "turn" is 0.75)."""
_WORD = re.compile(r"[a-z]+")
_REGEX_NAMES = frozenset({"other", "agent"})  # named groups of the patterns, not words


def reader_words() -> frozenset[str]:
    """Every word the reader's rule patterns spell out (their letter runs of `MIN_LETTERS` or more)."""
    return _words(tables()[0])


@cache
def _words(rules: tuple) -> frozenset[str]:
    words = {w for rule in rules for w in _WORD.findall(rule.pattern.pattern) if len(w) >= MIN_LETTERS}
    return frozenset(words - _REGEX_NAMES)


def near_misses(clause: str) -> list[tuple[str, str]]:
    """(typed word, the reader word it is closest to) for each word of `clause` the reader does not know but nearly
    does, in order; empty when every word is known or none is close to one."""
    known = reader_words()
    found = []
    for word in _WORD.findall(re.sub(r"@\w+", " ", clause.lower())):
        if len(word) < MIN_LETTERS or word in known:
            continue
        close = [w for w in difflib.get_close_matches(word, known, n=5, cutoff=CUTOFF) if _typo_of(word, w)]
        if close:
            found.append((word, close[0]))
    return found


def _typo_of(typed: str, word: str) -> bool:
    """A transposition or a letter added, dropped or changed: the lengths differ by at most one and the first
    letters agree (a different word that happens to look alike, "outrun" for "trun", is not its typo)."""
    return abs(len(typed) - len(word)) <= 1 and typed[0] == word[0]


def did_you_mean(clause: str) -> tuple[str, list[tuple[str, str]]] | None:
    """The clause with its near-misses corrected and the corrections, where the corrected clause reads and the
    clause itself does not; else None."""
    fixes = near_misses(clause)
    if not fixes or read_prompt(clause).read:
        return None
    fixed = clause
    for typed, word in fixes:
        fixed = re.sub(rf"\b{typed}\b", word, fixed, flags=re.IGNORECASE)
    return (fixed, fixes) if read_prompt(fixed).read else None
