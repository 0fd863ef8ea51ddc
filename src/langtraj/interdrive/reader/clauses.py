"""Reading a prompt clause by clause: `read_clauses` cuts the typed text where another agent starts a clause (a new
sentence; a comma, "and", "but", "then" or "after that" before a mention and its verb), gives each agent of a
coordinated subject ("@12 and @7 stop", "@693 @625 @635 stop") the predicate on its own, and reads each part with
`read_prompt`. A subordinate clause ("after @7 turns left, ...") or a part naming no agent ("2 seconds later, ...")
stays with the clause it qualifies, and a bare "and" after a mention ("lets @7 and @9 go first") joins objects, not
clauses. A clause put after another agent's ("@4 turns left, then @7 stops") keeps its sequence words in its
`condition` (`timing.py`): the clauses run at once.

See docs/interdrive.md ('Reading a prompt').
"""

from __future__ import annotations

import re
from contextlib import suppress
from dataclasses import replace

from langtraj.interdrive.reader.read import PromptReading, read_prompt
from langtraj.interdrive.reader.timing import SEQUENCE, joined, leading_sequence
from langtraj.interdrive.reader.when import trigger_of

_MENTION = r"@\d+(?!\w)"
_SUBJECTS = rf"{_MENTION}(?:\s*(?:,|and|&)?\s*{_MENTION})*"
_VERB_AFTER = r"\s+(?!(?:and|or|&)\b)[a-z']"
"""A mention starts a clause only when a word that is not a conjunction follows it."""
_SENTENCE = re.compile(r"[.!?;]+(?=\s|$)")
_JOIN = re.compile(
    rf"(?P<comma>\s*,\s*(?:(?:(?P<seq>{SEQUENCE})|and|but)\s*,?\s+)?|\s+(?:(?P<seq2>{SEQUENCE})|and|but)\s*,?\s+)"
    rf"(?={_SUBJECTS}{_VERB_AFTER})",
    re.IGNORECASE,
)
_SUBORDINATE = re.compile(
    r"^\s*(?:after(?!\s+(?:that|this)\b)|before|once|when|whenever|while|whilst|until|till|if|unless|because|since"
    r"|as\s+soon\s+as|as)\b",
    re.IGNORECASE,
)
_ENDS_WITH_MENTION = re.compile(rf"{_MENTION}\s*$")
_COORDINATED = re.compile(
    rf"^\s*(?:both\s+|all\s+of\s+|all\s+)?(?P<subjects>{_SUBJECTS})\s+(?P<rest>\S.*)$", re.IGNORECASE | re.DOTALL
)


_LEADING_CONDITION = re.compile(
    r"^\s*(?P<when>(?:when|whenever|once|as\s+soon\s+as|the\s+moment|the\s+instant|after(?!\s+(?:that|this)\b)|if)"
    rf"\b[^,;]*?{_MENTION}[^,;]*?)\s*,\s*(?P<rest>{_MENTION}.*)$",
    re.IGNORECASE | re.DOTALL,
)


def leading_condition(part: str) -> tuple[str, str]:
    """A part's leading condition clause and the rest ("When @1 is within 20 m of @7, @7 brakes hard": the "When ..."
    clause and "@7 brakes hard"), read apart so that the condition's mentions are not taken for the subject; ("",
    part) when it has none."""
    found = _LEADING_CONDITION.match(part)
    return ("", part) if found is None else (found.group("when").strip(), found.group("rest"))


def clauses(text: str) -> list[str]:
    """The parts of `text` read one by one (see the module): one per clause and agent, in order."""
    return [part for _, part in _parts(text)]


def _parts(text: str) -> list[tuple[str, str]]:
    """(sequence words before it, part) for each part of `text`: "then" in "@4 turns left, then @7 stops"."""
    parts: list[tuple[str, str]] = []
    for sentence in _SENTENCE.split(text):
        parts += _split_sentence(sentence)
    out = [(lead or leading_sequence(part), each) for lead, part in parts for each in _distribute(part)]
    return [(lead, p) for lead, p in out if p.strip()] or [("", text)]


def _split_sentence(sentence: str) -> list[tuple[str, str]]:
    pieces: list[tuple[str, str]] = []
    start, lead = 0, ""
    for join in _JOIN.finditer(sentence):
        left = sentence[start : join.start()]
        if not join.group("comma").strip(" ").startswith(",") and _ENDS_WITH_MENTION.search(left):
            continue  # "lets @7 and @9 go first": a bare "and" after a mention joins objects
        if left.strip():  # not a sentence's first words ("Afterwards @7 stops"): those lead the next piece
            pieces.append((lead, left))
            lead = ""
        start, lead = join.end(), join.group("seq") or join.group("seq2") or lead
    pieces.append((lead, sentence[start:]))
    merged: list[tuple[str, str]] = []
    for lead, piece in pieces:  # a subordinate clause, or a part naming nobody, goes with the clause after it
        if merged and (_SUBORDINATE.match(merged[-1][1]) or "@" not in merged[-1][1]):
            merged[-1] = (merged[-1][0], f"{merged[-1][1]}, {piece}")
        else:
            merged.append((lead, piece))
    return [(lead, p.strip()) for lead, p in merged if p.strip()]


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
    one clause, as `read_prompt` gives it. A clause after another agent's with sequence words ("then", "after that"),
    or a prompt starting with them, holds them in its `condition`."""
    parts = _parts(text)
    if len(parts) == 1:
        parts = [(leading_sequence(text), text)]
    readings: list[PromptReading] = []
    for lead, part in parts:
        when, rest = leading_condition(part)
        reading = replace(read_prompt(rest), clause=part)
        if when:
            reading = replace(reading, condition=joined(when, reading.condition))
        previous = readings[-1].agent if readings else None
        if lead and (not readings or reading.agent != previous):  # after another agent's clause
            reading = replace(reading, condition=joined(lead, reading.condition))
        if reading.condition and reading.agent is not None:
            with suppress(ValueError):  # a start LangTraj does not read: a strict reading refuses it (`trigger_of`)
                reading = replace(reading, trigger=trigger_of(reading.condition, reading.agent, previous))
        readings.append(reading)
    return tuple(readings)
