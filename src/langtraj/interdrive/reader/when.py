"""Timing words read as a trigger (`interdrive.triggers`): a time ("after 3 s", "at 4 s", "3 seconds from now"), a
distance or headway ("when @1 is within 20 m of @7", "once @1 is 2 s behind @7"), a stop or a pass ("once @4 has
stopped", "after @4 has passed @7") and a sequence ("@4 turns left, then @7 ..."; "then, 2 s later, ..."). Words
`timing.py` finds that say none of these ("eventually", "until @7 turns", "within 3 s") are refused by
`trigger_of` in one line naming them, never dropped. See docs/interdrive.md ('Timing in words').
"""

from __future__ import annotations

import re

from langtraj.interdrive.reader.timing import SEQUENCE
from langtraj.interdrive.triggers import AfterDone, AtTime, Passed, Stopped, Trigger, Within

_NUMBERS = {
    "one": 1, "two": 2, "three": 3, "four": 4, "five": 5, "six": 6, "seven": 7, "eight": 8, "nine": 9, "ten": 10,
    "eleven": 11, "twelve": 12, "fifteen": 15, "twenty": 20, "thirty": 30, "half a": 0.5,
}  # fmt: skip
_FIGURE = rf"\d+(?:\.\d+)?|{'|'.join(sorted(_NUMBERS, key=len, reverse=True))}"


def _n(name: str) -> str:
    """A figure, in a group of its own `name` (a pattern may hold several, each an alternative)."""
    return rf"(?P<{name}>{_FIGURE})"


_SECONDS = r"(?:s|secs?|seconds?)\b"
_METRES = r"(?:m|metres?|meters?)\b(?!/)"
_ABOUT = r"(?:(?:about|around|roughly|approximately|exactly|some|another)\s+)?"
_RUN = r"(?:the\s+)?(?:scenario|scene|simulation|run|episode|rollout|start|beginning)"
_AT_TIME = re.compile(
    rf"(?:(?:after|in|at)\s+{_ABOUT}{_n('n1')}\s*-?\s*{_SECONDS}(?:\s+(?:from\s+now|(?:from|after|into)\s+{_RUN}"
    rf"(?:\s+of\s+{_RUN})?))?"
    rf"|{_ABOUT}{_n('n2')}\s*-?\s*{_SECONDS}\s+(?:from\s+now|later|(?:from|after|into)\s+{_RUN}(?:\s+of\s+{_RUN})?)"
    rf"|at\s+(?:t|time|second)\s*=?\s*{_n('n3')}(?:\s*{_SECONDS})?)",
    re.IGNORECASE,
)
_WHEN = r"(?:(?:right|just|only|immediately)\s+)?(?:when|once|as\s+soon\s+as|the\s+moment|the\s+instant|after|if)\s+"
_WHO = r"@(?P<{}>\d+)"
_WITHIN = re.compile(
    rf"{_WHEN}{_WHO.format('a')}\s+(?:is|gets|comes|has\s+come|has\s+got(?:ten)?|drives|closes)\s+"
    rf"(?:(?:to\s+)?(?:within|closer\s+than|less\s+than|under|no\s+more\s+than)\s+)?{_ABOUT}{_n('n1')}\s*"
    rf"(?P<unit>{_METRES}|{_SECONDS})(?:\s+(?:or\s+less|or\s+closer))?"
    rf"(?:\s+(?:of|from|to|behind|ahead(?:\s+of)?|in\s+front(?:\s+of)?|away(?:\s+from)?)(?:\s+{_WHO.format('b')})?)?",
    re.IGNORECASE,
)
_STOPPED = re.compile(
    rf"{_WHEN}{_WHO.format('a')}\s+(?:has\s+stopped|stops|has\s+come\s+to\s+an?\s+(?:stop|halt)|comes\s+to\s+an?\s+"
    r"(?:stop|halt)|is\s+stopped|is\s+stationary|has\s+halted|halts|is\s+standing\s+still)",
    re.IGNORECASE,
)
_PASSED = re.compile(
    rf"{_WHEN}{_WHO.format('a')}\s+(?:has\s+passed|passes|has\s+gone\s+(?:past|by)|goes\s+(?:past|by)|has\s+overtaken"
    rf"|overtakes|is\s+past)(?:\s+{_WHO.format('b')})?",
    re.IGNORECASE,
)
_AFTER_CLAUSE = re.compile(rf"{_WHEN}@\d+\s+[a-z]", re.IGNORECASE)
_SEQUENCE = re.compile(rf",?\s*{SEQUENCE}\s*,?", re.IGNORECASE)
FORMS = (
    "'after 3 s', 'at 4 s', 'when @1 is within 20 m (or 2 s) of @7', 'once @4 has stopped', 'once @4 has passed @7', "
    "'@4 ..., then @7 ...'"
)
"""The timing words LangTraj reads, for the one line refusing others."""


def _number(found: re.Match[str]) -> float:
    """The figure a match of one of the patterns above holds."""
    low = next(v for k, v in found.groupdict().items() if k.startswith("n") and v is not None).lower()
    return float(_NUMBERS[low]) if low in _NUMBERS else float(low)


def trigger_of(words: str, agent: int, previous: int | None) -> Trigger:
    """The trigger timing `words` (a reading's `condition`, parts joined by " ... ") say for a clause asking
    `agent`, after a clause asking `previous` (None: none before); ValueError with the reason when they say none
    LangTraj reads."""
    parts = [p.strip(" ,") for p in words.split(" ... ") if p.strip(" ,")]
    sequence = [p for p in parts if _SEQUENCE.fullmatch(p)]
    rest = [p for p in parts if not _SEQUENCE.fullmatch(p)]
    if sequence:
        if previous is None:
            raise ValueError(f"{sequence[0]!r} follows no clause of another agent: say what comes first")
        if not rest:
            return AfterDone(previous)
        if len(rest) == 1 and (timed := _AT_TIME.fullmatch(rest[0])):
            return AfterDone(previous, _number(timed))
        raise ValueError(f"{words!r} says more than one when: give one time or condition after {sequence[0]!r}")
    if len(rest) != 1:
        raise ValueError(f"{words!r} says more than one when: give one (read: {FORMS})")
    return _one(rest[0], agent)


def _one(part: str, agent: int) -> Trigger:
    if timed := _AT_TIME.fullmatch(part):
        return AtTime(_number(timed))
    if near := _WITHIN.fullmatch(part):
        subject = int(near.group("a"))
        other = int(near.group("b")) if near.group("b") else agent
        if other == subject:
            raise ValueError(f"{part!r} names @{subject} twice: say within how far of whom")
        value = _number(near)
        if value <= 0:
            raise ValueError(f"{part!r}: a distance or time must be above 0")
        if re.fullmatch(_METRES, near.group("unit"), re.IGNORECASE):
            return Within(subject, other, metres=value)
        return Within(subject, other, seconds=value)
    if stop := _STOPPED.fullmatch(part):
        return Stopped(int(stop.group("a")))
    if passed := _PASSED.fullmatch(part):
        subject = int(passed.group("a"))
        other = int(passed.group("b")) if passed.group("b") else agent
        if other == subject:
            raise ValueError(f"{part!r}: @{subject} cannot pass itself")
        return Passed(subject, other)
    if _AFTER_CLAUSE.match(part):
        raise ValueError(
            f"{part!r}: a start after another agent's behaviour is read as a sequence; ask that behaviour in a "
            "clause of its own, then this one ('@4 turns left, then @7 ...')"
        )
    raise ValueError(f"{part!r} is not a start LangTraj reads (it reads {FORMS})")
