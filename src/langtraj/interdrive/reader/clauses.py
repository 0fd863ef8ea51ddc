"""Reading a prompt clause by clause: `read_clauses` cuts the typed text where another agent starts a clause (a new
sentence; a comma, "and", "but" or "then" before a mention and its verb), gives each agent of a coordinated subject
("@12 and @7 stop", "@693 @625 @635 stop") the predicate on its own, and reads each part with `read_prompt`. A
subordinate clause ("after @7 turns left, ...") stays with the clause it qualifies, and a bare "and" after a mention
("lets @7 and @9 go first") joins objects, not clauses.

See docs/interdrive.md ('Reading a prompt').
"""

from __future__ import annotations

import re
from dataclasses import replace

from langtraj.interdrive.reader.read import PromptReading, read_prompt

_MENTION = r"@\d+(?!\w)"
_SUBJECTS = rf"{_MENTION}(?:\s*(?:,|and|&)?\s*{_MENTION})*"
_VERB_AFTER = r"\s+(?!(?:and|or|&)\b)[a-z']"
"""A mention starts a clause only when a word that is not a conjunction follows it."""
_SENTENCE = re.compile(r"[.!?;]+(?=\s|$)")
_JOIN = re.compile(
    rf"(?P<comma>\s*,\s*(?:(?:and\s+then|and|but|then)\s+)?|\s+(?:and\s+then|and|but|then)\s+)(?={_SUBJECTS}{_VERB_AFTER})",
    re.IGNORECASE,
)
_SUBORDINATE = re.compile(
    r"^\s*(?:after|before|once|when|whenever|while|whilst|until|till|if|unless|because|since|as\s+soon\s+as|as)\b",
    re.IGNORECASE,
)
_ENDS_WITH_MENTION = re.compile(rf"{_MENTION}\s*$")
_COORDINATED = re.compile(
    rf"^\s*(?:both\s+|all\s+of\s+|all\s+)?(?P<subjects>{_SUBJECTS})\s+(?P<rest>\S.*)$", re.IGNORECASE | re.DOTALL
)


def clauses(text: str) -> list[str]:
    """The parts of `text` read one by one (see the module): one per clause and agent, in order."""
    parts: list[str] = []
    for sentence in _SENTENCE.split(text):
        parts += _split_sentence(sentence)
    out: list[str] = []
    for part in parts:
        out += _distribute(part)
    return [p for p in out if p.strip()] or [text]


def _split_sentence(sentence: str) -> list[str]:
    pieces: list[str] = []
    start = 0
    for join in _JOIN.finditer(sentence):
        left = sentence[start : join.start()]
        if not join.group("comma").strip(" ").startswith(",") and _ENDS_WITH_MENTION.search(left):
            continue  # "lets @7 and @9 go first": a bare "and" after a mention joins objects
        pieces.append(left)
        start = join.end()
    pieces.append(sentence[start:])
    merged: list[str] = []
    for piece in pieces:  # a subordinate clause goes with the clause after it
        if merged and _SUBORDINATE.match(merged[-1]):
            merged[-1] = f"{merged[-1]}, {piece}"
        else:
            merged.append(piece)
    return [p.strip() for p in merged if p.strip()]


def _distribute(part: str) -> list[str]:
    """ "@12 and @7 stop" -> ["@12 stop", "@7 stop"]; any other part unchanged."""
    found = _COORDINATED.match(part)
    if found is None:
        return [part]
    subjects = re.findall(_MENTION, found.group("subjects"))
    if len(subjects) < 2:
        return [part]
    return [f"{subject} {found.group('rest')}" for subject in subjects]


def read_clauses(text: str) -> tuple[PromptReading, ...]:
    """Each clause of `text` read (`clauses`, `read_prompt`), its `clause` the part read: one reading for a prompt of
    one clause, as `read_prompt` gives it."""
    parts = clauses(text)
    if len(parts) == 1:
        return (replace(read_prompt(text), clause=text),)
    return tuple(replace(read_prompt(part), clause=part) for part in parts)
