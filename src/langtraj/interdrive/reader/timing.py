"""Timing words found, so that they are never dropped: a time ("after 2 seconds", "in 3 s", "2 seconds from now", "at
4 s", "at t = 4"), a condition ("when @1 is 20 m behind", "once @7 has turned left", "if @7 stops", "until @7 turns")
and a sequence across agents ("then", "after that", "afterwards" before another agent's clause: `SEQUENCE`, found by
`clauses.py`). They are kept on the reading (`PromptReading.condition`); `when.py` reads those that say a start as
its trigger, and a strict reading refuses the others, saying why; a description names them either way.

Not a timing: words inside a behaviour's own phrase ("waits until @7 has gone by", "goes before @7"), a turn's or a
stop's place ("turns left when it reaches the junction"), a yield's "until @7 has passed", hedges ("if needed",
"when safe") and a time gap ("at 2 s headway").

See docs/interdrive.md ('Reading a prompt').
"""

from __future__ import annotations

import re
from collections.abc import Sequence

from langtraj.interdrive.behaviour import Behaviour

Span = tuple[int, int]

_NUMBER = (
    r"(?:\d+(?:\.\d+)?|one|two|three|four|five|six|seven|eight|nine|ten|eleven|twelve|fifteen|twenty|thirty"
    r"|a\s+few|a\s+couple(?:\s+of)?|several|half\s+a)"
)
_UNIT = r"(?:s|secs?|seconds?|ms|mins?|minutes?)\b(?!/)"
_DURATION = rf"{_NUMBER}\s*-?\s*{_UNIT}"
_ABOUT = r"(?:(?:about|around|roughly|approximately|exactly|just|some|another|only)\s+)?"
_NOT_GAP = r"(?!\s+(?:of\s+)?(?:headway|gap|time\s+gap|apart|behind|ahead|following|distance|of\b))"
"""Not a time gap: "at 2 s headway", "within 2 s of @7"."""
_RUN = r"(?:the\s+)?(?:scenario|scene|simulation|run|episode|rollout|start|beginning)"
_TIMES = (
    rf"\b(?:after|in|within|at)\s+{_ABOUT}{_DURATION}{_NOT_GAP}"
    rf"(?:\s+(?:from\s+now|(?:from|after|into)\s+{_RUN}(?:\s+of\s+{_RUN})?))?",
    rf"\b{_ABOUT}{_DURATION}\s+(?:from\s+now|later|(?:from|after|into)\s+{_RUN}(?:\s+of\s+{_RUN})?)\b",
    rf"\bat\s+(?:t|time|step|second)\s*=?\s*\d+(?:\.\d+)?(?:\s*{_UNIT})?",
    rf"\b(?:after|with)\s+a\s+(?:short\s+|brief\s+|little\s+|small\s+)?(?:while|moment|bit|delay|pause|wait)\b"
    rf"(?:\s+of\s+{_DURATION})?",
    r"\b(?:(?:a\s+(?:bit|little|moment|while)|shortly|much|slightly|soon)\s+)?later(?:\s+on)?\b",
    r"\bafter\s+some\s+time\b|\beventually\b",
)
TIMES = re.compile("|".join(f"(?:{p})" for p in _TIMES))
"""A time to act at, after or within."""

_REST = r"(?:[^,;!?:.]|\.(?=\d))+"
"""The rest of a clause (a decimal point does not end it)."""
_HEDGE = r"(?:needed|necessary|possible|required|safe|appropriate|it\s+is\s+safe|it's\s+safe|it\s+can|you\s+can|so)\b"
_SUBJECT = (
    r"(?:<m\d+>|(?:it|he|she|they)\s+\w|the\s+(?:ego|other\b|(?:traffic\s+)?lights?\b|signal\b|\w+\s+(?:car|vehicle"
    r"|truck|lorry|van|bus|cyclist|pedestrian)\b))"
)
_LEAD = r"(?:(?:right|just|only|immediately|shortly|soon|not)\s+)?"
_CONDITIONS = (
    rf"\b{_LEAD}(?P<when>when|whenever|(?<!at\s)once(?!\s+(?:again|more)\b)|as\s+soon\s+as|if|unless"
    rf"|by\s+the\s+time|the\s+moment|the\s+instant|as\s+long\s+as|provided(?:\s+that)?)\s+(?!{_HEDGE}){_REST}",
    rf"\b{_LEAD}(?P<after>after|before|until|till)\s+(?={_SUBJECT}){_REST}",
)
CONDITIONS = re.compile("|".join(f"(?:{p})" for p in _CONDITIONS))
"""A subordinate clause saying when: "when @1 is 20 m behind", "after @7 turns left", "until the light turns"."""
_SUBORDINATOR = re.compile(
    rf"{_LEAD}(?:when|whenever|once|as\s+soon\s+as|if|unless|by\s+the\s+time|the\s+moment|the\s+instant|as\s+long\s+as"
    r"|provided(?:\s+that)?|after|before|until|till)\s*"
)

SEQUENCE = r"(?:and\s+)?(?:then|after\s+that|after\s+this|afterwards?|subsequently|next)"
"""Words putting a clause after the one before it ("@4 turns left, then @7 pulls out ...")."""
_SEQUENCE = re.compile(rf"(?:{SEQUENCE})", re.IGNORECASE)

_WHO = r"(?:it|he|she|they|<m(?P<who>\d+)>)"
_PLACE = (
    r"(?:the|a)\s+(?:next\s+|first\s+|upcoming\s+)?(?:junction|intersection|crossroads|roundabout|lights|traffic\s+lights"
    r"|corner|crossing|crosswalk|stop\s+line|stop\s+sign|end\s+of\s+the\s+(?:road|street))"
)
_AT_PLACE = re.compile(
    rf"(?:when|once|as\s+soon\s+as|after|before)\s+{_WHO}\s+(?:reaches|gets\s+to|arrives\s+at|comes\s+to|approaches"
    rf"|is\s+at|enters|hits|gets\s+there)\s+{_PLACE}\s*"
)
"""Where a turn or a stop happens ("turns left when it reaches the junction"): its target's place, honoured."""
_PASSED = re.compile(
    rf"(?:until|till|after|once|when)\s+{_WHO}\s+(?:has\s+|have\s+)?(?:passed|passes|pass|gone(?:\s+(?:by|through|past))?"
    r"|goes\s+(?:by|through|past)|crossed|crosses|cleared|clears|got\s+through|gets\s+through|is\s+(?:past|through|clear"
    r"|gone))\b[^,;!?:.]*"
)
"""A yield's "until @7 has passed": what yielding is."""
_ARRIVES = re.compile(
    rf"before\s+{_WHO}\s+(?:does|can|arrives|gets\s+there|reaches|goes|crosses|enters|comes)\b[^,;!?:.]*"
)
"""Going first's "before @7 arrives": what going first is."""


def _at_the_place() -> frozenset[Behaviour]:
    """The kinds whose target is at the next junction or stop line (asked when called: behaviours register late)."""
    return frozenset(
        {Behaviour.TURN_LEFT, Behaviour.TURN_RIGHT, Behaviour.GO_STRAIGHT, Behaviour.STOP, Behaviour.YIELD,
         Behaviour.GO_FIRST, Behaviour.RUN_RED_LIGHT}
    )  # fmt: skip


def timing_spans(
    text: str,
    phrases: Sequence[Span],
    asked: int | None = None,
    other: int | None = None,
    behaviour: Behaviour | None = None,
    sequence: Span | None = None,
) -> list[Span]:
    """The spans of the normalised `text` (mentions as `<m0>`, ...) holding a time or a condition, in order. Words
    starting inside `phrases` (the behaviour phrases found) are a phrase's own, a time inside `sequence` (a manoeuvre
    and then a stop read: "turns left and later stops") the sequence's; `asked` and `other` are the placeholder
    numbers of the agent asked and its other agent, `behaviour` the kind read (what it honours)."""
    found: list[Span] = []
    for pattern in (TIMES, CONDITIONS):
        inside = [*phrases, *([sequence] if sequence and pattern is TIMES else [])]
        for m in pattern.finditer(text):
            start = m.start()
            if any(s <= start < e for s, e in inside) and pattern is CONDITIONS:  # "turn right when ...": "when ..."
                start = m.start("when") if m.group("when") else m.start("after")
            end = _trim(text, start, m.end(), asked)
            outside = end > start and not any(s <= start < e for s, e in inside)
            if outside and not _honoured(text[start:end], asked, other, behaviour):
                found.append((start, end))
    kept: list[Span] = []
    for span in sorted(found, key=lambda s: (s[0] - s[1], s[0])):  # longest first
        if all(span[1] <= s or span[0] >= e for s, e in kept):
            kept.append(span)
    return sorted(kept)


def _trim(text: str, start: int, end: int, asked: int | None) -> int:
    """A leading condition ends before the asked agent's mention ("when @1 is 20 m behind @741 brakes hard"), and
    before trailing spaces."""
    if asked is not None:
        for mention in re.finditer(rf"<m{asked}>", text[start:end]):
            if not _SUBORDINATOR.fullmatch(text[start : start + mention.start()]):
                end = start + mention.start()
                break
    return len(text[:end].rstrip(" ,"))


def _honoured(words: str, asked: int | None, other: int | None, behaviour: Behaviour | None) -> bool:
    """Whether condition `words` only restate what `behaviour` does: a turn's or a stop's place, a yield's "until @7
    has passed", going first's "before @7 arrives" (of the asked agent or a pronoun; of the other agent)."""
    if behaviour is None:
        return False
    checks = [(_PASSED, other, Behaviour.YIELD), (_ARRIVES, other, Behaviour.GO_FIRST)]
    if behaviour in _at_the_place():
        checks.append((_AT_PLACE, asked, behaviour))
    for pattern, whom, kind in checks:
        said = pattern.fullmatch(re.sub(rf"^{_LEAD}", "", words))
        if said and behaviour is kind and (said.group("who") is None or int(said.group("who")) == whom):
            return True
    return False


def leading_sequence(part: str) -> str:
    """The sequence words a typed clause starts with before a mention ("Then @7 stops": "Then"), or ""."""
    found = re.match(rf"\s*({SEQUENCE})\b\s*,?\s*(?=@\w)", part, re.IGNORECASE)
    return found.group(1) if found else ""


def kind_of(words: str) -> str:
    """What timing `words` are: "sequence", "time", "condition", or "timing" when they hold several."""
    kinds = set()
    for part in words.split(" ... "):
        if _SEQUENCE.fullmatch(part.strip()):
            kinds.add("sequence")
        elif TIMES.fullmatch(part.lower()):
            kinds.add("time")
        else:
            kinds.add("condition")
    return kinds.pop() if len(kinds) == 1 else "timing"


def joined(*parts: str) -> str:
    """Timing words of one clause as one string, each part once."""
    out: list[str] = []
    for part in parts:
        if part and part.lower() not in (o.lower() for o in out):
            out.append(part)
    return " ... ".join(out)


def condition_note(words: str) -> str:
    """One phrase for a description: "the time 'after 2 seconds' is not read (the behaviour runs at once)"."""
    return f"the {kind_of(words)} {words!r} is not read (the behaviour runs at once)"
