"""Reading one prompt: `read_prompt` normalises the typed text (lower case, collapsed whitespace, each `@id` mention
a placeholder), finds every rule's matches (`rules.py`), keeps the longest that do not overlap, drops those in an
'instead of' clause, finds the subject of each and the agent asked (addressed, named by a request, or the subject of
the first main-clause phrase), and gives a `PromptReading`: one kind (toward one other agent for a pair kind), or
none and the reason (negated, passive, several agents or kinds, no subject or phrase found).

See docs/interdrive.md ('Reading a prompt').
"""

from __future__ import annotations

import re
from collections.abc import Collection, Iterable, Sequence
from contextlib import suppress
from dataclasses import dataclass, replace

from langtraj.interdrive.adherence import Fact
from langtraj.interdrive.behaviour import BEHAVIOURS, Behaviour, behaviour_facts
from langtraj.interdrive.behaviours.base import kind
from langtraj.interdrive.prompts.compose import MENTION, mentions_in
from langtraj.interdrive.reader.alone import lone_reason
from langtraj.interdrive.reader.rules import (
    CONTRAST,
    NEGATION,
    PASSIVE,
    PLACEHOLDER,
    SLOT,
    tables,
    verb,
)
from langtraj.interdrive.reader.timing import condition_note, timing_spans
from langtraj.interdrive.reader.when import trigger_of
from langtraj.interdrive.taxonomy import SUBTYPES_BY_ID
from langtraj.interdrive.triggers import Trigger

# ---------------------------------------------------------------------------------------------- clauses and subjects

_CLAUSE_BREAK = re.compile(r"[,;.!?:]|\b(?:and|but|then|or)\b")
_SUBORDINATOR = re.compile(
    r"\b(?:after|before|once|when|whenever|while|whilst|as\s+soon\s+as|until|till|if|unless|because|since|so|as)\b"
)
_FILLER = (
    r"(?:can|could|should|must|will|would|may|might|shall|to|has\s+to|have\s+to|needs?\s+to|is|are|is\s+going\s+to"
    r"|going\s+to|gonna|ought\s+to|had\s+better|please|then|just|also|now|simply|first|gently|quickly|slowly"
    r"|carefully|immediately|safely|smoothly|soon|promptly|'ll|'d|really|definitely|only|still)"
)
_LOCAL_SUBJECT = re.compile(rf"(<m\d+>)\s*[,:]?\s*(?:{_FILLER}\s+)*$")
_COORDINATED = re.compile(rf"{SLOT}\s*(?:,|and|or|&)\s*(<m\d+>)\s*[,:]?\s*(?:{_FILLER}\s+)*$")
_PRONOUN_SUBJECT = re.compile(rf"\b(?:it|he|she|they|you)\s+(?:{_FILLER}\s+)*$")
_VOCATIVE = re.compile(
    r"^(?:(?:hey|ok|okay|now|right|so|please|alright|and)\s*,?\s*)?(<m\d+>)\s*[,:;]|[,;:]\s*(<m\d+>)\s*[.!]?\s*$"
)
_REQUEST_VERBS = verb(
    "have", "get", "make", "tell", "ask", "want", "need", "like", "let", "allow", "order", "instruct", "force", "see",
    "expect", "make sure", "ensure",
)  # fmt: skip
_CAUSATIVE = re.compile(rf"\b{_REQUEST_VERBS}\s+(?:that\s+)?(<m\d+>)")


# ---------------------------------------------------------------------------------------------- the reading


@dataclass(frozen=True)
class PromptReading:
    """What a prompt asks: `behaviour` of track `agent` (toward track `other` for a pair kind), decided by `words`
    of the text; or `behaviour` None and the `reason` nothing was read (`agent` is still set where it was found)."""

    behaviour: Behaviour | None
    agent: int | None
    other: int | None = None
    words: str = ""
    reason: str = ""
    also: tuple[Behaviour, ...] = ()
    """Kinds asked with `behaviour` that it subsumes ("pulls over and comes to a stop": stop), the fallback a
    simulation steers by where the map gives `behaviour` no target (`sim.prompts`)."""
    then: Behaviour | None = None
    """A kind asked after `behaviour` is done ("turns left and then stops": stop), steered and judged with it (a
    turn or a lane change, then a stop: `rules.tables()`)."""
    clause: str = ""
    """The part of the typed prompt read (`clauses.read_clauses`; the whole text for a prompt of one clause)."""
    metres: float | None = None
    """A distance the text gives ("with a 10 m gap", "8 metres ahead of @7"): a cut-in's gap (None: none given)."""
    deceleration: float | None = None
    """A deceleration the text gives in m/s^2 ("at 6 m/s^2", "at 0.5 g"): how hard a braking lead brakes (None:
    none given)."""
    condition: str = ""
    """Timing words, as typed (`timing.py`: "after 2 seconds", "when @1 is 20 m behind", "then" before another agent's
    clause; several joined by " ... "); empty when none."""
    trigger: Trigger | None = None
    """When the behaviour starts, as its `condition` says (`when.trigger_of`); None when it starts at once, or when
    the condition says no start LangTraj reads (a strict reading refuses it: `when.trigger_of` says why)."""

    @property
    def read(self) -> bool:
        return self.behaviour is not None

    def followed(self, found: frozenset[Fact]) -> bool | None:
        """Whether the facts the labelers `found` in a rollout follow this reading (None: nothing read, or a pair
        behaviour without its other agent): the one rule of the studio, the suites and instruction following. A
        typed prompt names no interaction subtype, so a pair behaviour is followed when the detector finds the
        interaction of its type between the two agents, whatever the subtype (a cut-in: its own subtype)."""
        if self.behaviour is None or self.agent is None:
            return None
        spec = BEHAVIOURS[self.behaviour]
        if self.then is not None and not behaviour_facts(self.then, self.agent) <= found:
            return False
        if not spec.is_pair:
            return behaviour_facts(self.behaviour, self.agent) <= found
        if self.other is None:
            return None
        return any(
            fact[0] == "interaction"
            and fact[1:3] == (self.agent, self.other)
            and (fact[3] == spec.subtype if spec.exact else SUBTYPES_BY_ID[str(fact[3])].type is spec.interaction)
            for fact in found
        )

    def unjudged(self, present: Collection[int]) -> str | None:
        """Why this reading cannot be judged on a scene holding the tracks `present` (nothing read, an agent it names
        absent, a pair behaviour without its other agent), or None when `followed` can judge it."""
        if not self.read:
            return f"not read ({self.reason})"
        missing = [f"@{t}" for t in (self.agent, self.other) if t is not None and t not in present]
        if missing:
            return f"{', '.join(missing)} not in the scene"
        if self.agent is None or (BEHAVIOURS[self.behaviour].is_pair and self.other is None):
            return "a pair behaviour without its other agent"
        return None

    def describe(self) -> str:
        """One line: `read as: @12 turn_left ("hang a left")`, `read as: @12 cut_in @7, gap 15 m ("cuts in front of
        @7")` (every parameter, "(default)" where the text gives none), or
        `not read: <reason>; the prompt steers by text alone`; then its start where its timing words give one
        (`; starts from 3 s ('after 3 s')`), else the timing words not read, if any (`; the time 'eventually' is not
        read (the behaviour runs at once)`)."""
        if self.behaviour is None:
            line = f"not read: {self.reason}; the prompt steers by text alone"
        else:
            toward = f" @{self.other}" if self.other is not None else ""
            then = f" then {self.then.value}" if self.then is not None else ""
            figures = self.figures()
            asked = "".join(f", {p.describe(figures[p.reads])}" for p in kind(self.behaviour).parameters)
            line = f'read as: @{self.agent} {self.behaviour.value}{toward}{then}{asked} ("{self.words}")'
            unused = self.unused_figures()
            if unused:
                line += f"; {', '.join(repr(u) for u in unused)} not read: {self.behaviour.value} takes no such figure"
        if self.trigger is not None:
            return f"{line}; starts {self.trigger.describe()}" + (f" ({self.condition!r})" if self.condition else "")
        return f"{line}; {condition_note(self.condition)}" if self.condition else line

    def figures(self) -> dict[str, float | None]:
        """The figures the text gives, by kind (`Parameter.reads`): a distance, a deceleration."""
        return {"metres": self.metres, "deceleration": self.deceleration}

    def asked(self) -> dict[str, float]:
        """The behaviour's parameters as the text asks them (`BehaviourKind.parameters`): each from its figure of the
        text, its default where the text gives none; a figure outside its parameter's accepted range raises a
        one-line InputError (`Parameter.check`). Empty when nothing was read."""
        return {} if self.behaviour is None else kind(self.behaviour).asked(self.figures())

    def unused_figures(self) -> list[str]:
        """The figures of the text that no parameter of the behaviour reads ("5 m" asked of a tailgate): words that
        would be dropped."""
        if self.behaviour is None:
            return []
        taken = {p.reads for p in kind(self.behaviour).parameters}
        units = {"metres": "m", "deceleration": "m/s^2"}
        return [f"{v:g} {units[k]}" for k, v in self.figures().items() if v is not None and k not in taken]

    def to_json(self) -> dict[str, object]:
        return {
            "behaviour": None if self.behaviour is None else self.behaviour.value,
            "agent": self.agent,
            "other": self.other,
            "words": self.words,
            "reason": self.reason,
            "also": [b.value for b in self.also],
            "then": None if self.then is None else self.then.value,
            "clause": self.clause,
            "metres": self.metres,
            "deceleration": self.deceleration,
            "condition": self.condition,
            "trigger": None if self.trigger is None else self.trigger.describe(),
        }


@dataclass(frozen=True)
class _Match:
    behaviour: Behaviour
    start: int
    end: int
    other: int | None  # placeholder index of the other agent the phrase names
    agent: int | None = None  # placeholder index of the agent it names as the object of a request


@dataclass(frozen=True)
class _Text:
    """The prompt lower-cased, whitespace collapsed, mentions as `<m0>`, `<m1>`, ... (index into `ids`), with the
    position in the typed text of every character."""

    text: str
    origin: tuple[int, ...]
    ids: tuple[int, ...]

    def span(self, typed: str, start: int, end: int) -> str:
        return typed[self.origin[start] : self.origin[end - 1] + 1]


def _normalise(typed: str) -> _Text:
    ids = mentions_in(typed)
    index = {track: i for i, track in enumerate(ids)}
    chars: list[str] = []
    origin: list[int] = []
    pos = 0
    for mention in [*MENTION.finditer(typed), None]:
        stop = len(typed) if mention is None else mention.start()
        for i in range(pos, stop):
            char = typed[i].replace("\u2019", "'").replace("\u2018", "'")
            if char.isspace():
                if chars and chars[-1] != " ":
                    chars.append(" ")
                    origin.append(i)
                continue
            for lower in char.lower():
                chars.append(lower)
                origin.append(i)
        if mention is not None:
            slot = f"<m{index[int(mention.group(1))]}>"
            chars.extend(slot)
            origin.extend([mention.start()] * (len(slot) - 1) + [mention.end() - 1])
            pos = mention.end()
    return _Text("".join(chars), tuple(origin), ids)


_METRES = re.compile(r"\b(\d+(?:\.\d+)?)\s*(?:m|metres?|meters?)\b(?!/)")
"""A distance in metres ("10 m", "8.5 metres"; not a speed, "10 m/s")."""
_DECELERATION = re.compile(r"\b(\d+(?:\.\d+)?)\s*(m/s\^?2|m/s²|m/s/s|g)(?!\w)")
"""A deceleration in m/s^2 or in g ("6 m/s^2", "0.5 g")."""
STANDARD_GRAVITY = 9.80665


def _slot(placeholder: str | None) -> int | None:
    return None if placeholder is None else int(placeholder[2:-1])


def _candidates(text: str) -> list[_Match]:
    """Every rule's matches, longest first (ties: the earlier rule)."""
    found = []
    for order, rule in enumerate(tables()[0]):
        for m in rule.pattern.finditer(text):
            if m.end() > m.start():
                named = m.groupdict()
                other, agent = _slot(named.get("other")), _slot(named.get("agent"))
                found.append((-(m.end() - m.start()), order, _Match(rule.behaviour, m.start(), m.end(), other, agent)))
    return [match for _, _, match in sorted(found, key=lambda item: (item[0], item[1], item[2].start))]


def _select(candidates: Sequence[_Match], banned: Iterable[_Match] = ()) -> list[_Match]:
    """The candidates not banned that no longer one overlaps, in order of start."""
    kept: list[_Match] = []
    for match in candidates:
        if match not in banned and _outside(kept, match.start, match.end):
            kept.append(match)
    return sorted(kept, key=lambda m: m.start)


def _outside(matches: Sequence[_Match], start: int, end: int) -> bool:
    return all(end <= m.start or start >= m.end for m in matches)


def _clause_start(text: str, pos: int) -> int:
    breaks = [b.end() for b in _CLAUSE_BREAK.finditer(text, 0, pos)]
    return breaks[-1] if breaks else 0


def _local_subject(text: str, match: _Match, matches: Sequence[_Match]) -> int | str | None:
    """The mention right before a phrase (its subject: "@7 can cross first"), "several" for "@12 and @7 stop",
    "pronoun" for "it goes first", or None. A mention that is the object of an earlier phrase is the subject of an
    infinitive only ("waits for @7 to turn left", not "waits for @7, then turns left")."""
    if match.agent is not None:
        return match.agent
    before = text[: match.start]
    if _COORDINATED.search(before):
        return "several"
    found = _LOCAL_SUBJECT.search(before)
    if found:
        infinitive = re.fullmatch(r"\s*to\s+", before[found.end(1) :]) is not None
        return _slot(found.group(1)) if infinitive or _outside(matches, found.start(1), found.end(1)) else None
    return "pronoun" if _PRONOUN_SUBJECT.search(before) else None


def _is_subordinate(text: str, match: _Match, matches: Sequence[_Match]) -> bool:
    """Whether a phrase is in a subordinate clause ("after @7 turns left, ...")."""
    start = _clause_start(text, match.start)
    return any(_outside(matches, s.start(), s.end()) for s in _SUBORDINATOR.finditer(text, start, match.start))


def _main_subject(text: str, matches: Sequence[_Match], subjects: Sequence[int | str | None]) -> int | None:
    """The agent asked: the one addressed ("@7, ..." or "..., @12"), the one a request names ("have @7 ...",
    "I want @12 to ..."), the subject of the first main-clause phrase, or the first mention no phrase names as the
    other agent."""
    vocative = _VOCATIVE.search(text)
    others = {m.other for m in matches}
    if vocative and (vocative.group(1) or _slot(vocative.group(2)) not in others):
        return _slot(vocative.group(1) or vocative.group(2))
    causative = _CAUSATIVE.search(text)
    if causative and "<m" not in text[: causative.start()]:
        return _slot(causative.group(1))
    for match, subject in zip(matches, subjects, strict=True):
        if isinstance(subject, int) and not _is_subordinate(text, match, matches):
            return subject
    return next((int(i) for i in PLACEHOLDER.findall(text) if int(i) not in others), None)


def _not_read(reason: str, agent: int | None = None) -> PromptReading:
    return PromptReading(None, agent, reason=reason)


def _analyse(
    text: str, candidates: Sequence[_Match], banned: Sequence[_Match] = ()
) -> tuple[list[_Match], list[int | str | None], int | None]:
    """The phrases read (less those in an 'instead of' clause), the subject of each and the agent asked."""
    matches = _select(candidates, banned)
    contrast = [(c.start(), c.end()) for c in CONTRAST.finditer(text) if _outside(matches, c.start(), c.start() + 1)]
    matches = [m for m in matches if not any(s <= m.start < e for s, e in contrast)]
    subjects = [_local_subject(text, m, matches) for m in matches]
    return matches, subjects, _main_subject(text, matches, subjects)


def read_prompt(text: str) -> PromptReading:
    """The behaviour kind `text` asks of which agent (mentions are `@<track id>`), or None and why, with the timing
    words it does not honour (`condition`). See the module."""
    norm = _normalise(text)
    if not norm.ids:
        return _not_read("names no agent (@<track id>)")
    candidates = _candidates(norm.text)
    return _finish(text, norm, candidates, _read(text, norm, candidates))


def _finish(text: str, norm: _Text, candidates: Sequence[_Match], reading: PromptReading) -> PromptReading:
    """`reading` with its timing words (`timing.timing_spans`), and the reason a pair kind's words alone or an
    overtake alone are not read (`alone.lone_reason`)."""
    slots: dict[int | None, int] = {track: i for i, track in enumerate(norm.ids)}
    asked, other = slots.get(reading.agent), slots.get(reading.other)
    phrases = _select(candidates)
    requests = [m for m in phrases if m.other is not None and m.other == asked]
    phrases = _select(candidates, requests) if requests else phrases  # as `_read` reads "Let @7 turn left"
    spans = [(m.start, m.end) for m in phrases]
    kept = [m for m in phrases if reading.then is not None and m.behaviour in (reading.behaviour, reading.then)]
    sequence = (min(m.start for m in kept), max(m.end for m in kept)) if kept else None  # "turns left, later stops"
    if reading.reason == "no behaviour phrase found":
        lone = lone_reason(norm.text, norm.ids, asked)
        reading = reading if lone is None else replace(reading, reason=lone)
    found = timing_spans(norm.text, spans, asked, other, reading.behaviour, sequence)
    condition = " ... ".join(norm.span(text, s, e) for s, e in found)
    if not condition:
        return reading
    if reading.metres is not None:  # a distance in the timing words is the trigger's, not the behaviour's
        outside = [m for m in _METRES.finditer(norm.text) if not any(s <= m.start() < e for s, e in found)]
        reading = replace(reading, metres=float(outside[0].group(1)) if outside else None)
    trigger = None
    if reading.agent is not None:
        with suppress(ValueError):  # a start LangTraj does not read: a strict reading refuses it (`trigger_of`)
            trigger = trigger_of(condition, reading.agent, None)
    return replace(reading, condition=condition, trigger=trigger)


def _read(text: str, norm: _Text, candidates: Sequence[_Match]) -> PromptReading:
    low = norm.text
    matches, subjects, subject_slot = _analyse(low, candidates)
    requests = [m for m in matches if m.other is not None and m.other == subject_slot]
    if requests:  # "Let @7 turn left": a request to the agent it names, not a yield to it
        matches, subjects, subject_slot = _analyse(low, candidates, requests)
    agent = None if subject_slot is None else norm.ids[subject_slot]
    negations = [n for n in NEGATION.finditer(low) if _outside(matches, n.start(), n.end())]
    if negations:
        return _not_read(f"negated ({norm.span(text, negations[0].start(), negations[0].end())!r})", agent)
    passive = PASSIVE.search(low)
    if passive:
        return _not_read("passive voice", agent)
    if "several" in subjects:
        return _not_read("asks several agents at once", agent)
    if subject_slot is None:
        return _not_read("cannot tell which agent is asked", agent)
    matches = [m for m, s in zip(matches, subjects, strict=True) if not isinstance(s, int) or s == subject_slot]
    asked = {m.behaviour for m in matches}
    subsumes = tables()[1]
    kinds = asked - {k for kind in asked for k in subsumes.get(kind, ())}
    if not kinds:
        return _not_read("no behaviour phrase found", agent)
    if len(kinds) > 1:
        return _sequence(text, norm, kinds, matches, agent)
    (kind,) = kinds
    decided = [m for m in matches if m.behaviour is kind]
    if not BEHAVIOURS[kind].is_pair:
        best = max(decided, key=lambda m: (m.end - m.start, -m.start))
        also = tuple(b for b in Behaviour if b in asked and b in subsumes.get(kind, ()))
        return PromptReading(kind, agent, None, norm.span(text, best.start, best.end), also=also)
    return _pair_reading(text, norm, kind, decided, subject_slot)


def _sequence(
    text: str, norm: _Text, kinds: set[Behaviour], matches: Sequence[_Match], agent: int | None
) -> PromptReading:
    """Two kinds asked of one agent: a manoeuvre and then what follows it (`rules.tables()`: "turns left and then
    stops"), in that order; anything else is not read, saying what is."""
    named = ", ".join(b.value for b in Behaviour if b in kinds)
    then_kinds = tables()[2]
    pairs = [(first, then) for first in kinds for then in kinds if then in then_kinds.get(first, ())]
    if len(kinds) != 2 or not pairs:
        return _not_read(
            f"asks for more than one behaviour ({named}); of two for one agent, only a turn or a lane change and then "
            "a stop is read",
            agent,
        )
    ((first, then),) = pairs
    before = min((m for m in matches if m.behaviour is first), key=lambda m: m.start)
    after = max((m for m in matches if m.behaviour is then), key=lambda m: m.end)
    if after.start < before.start:
        return _not_read(
            f"asks {then.value} before {first.value}; only a {first.value} and then a {then.value} is read"
        )
    return PromptReading(first, agent, None, norm.span(text, before.start, after.end), then=then)


def _pair_reading(text: str, norm: _Text, kind: Behaviour, decided: Sequence[_Match], subject: int) -> PromptReading:
    agent = norm.ids[subject]
    named = {m.other for m in decided if m.other is not None}
    if len(named) > 1:
        return _not_read(f"{kind.value} names more than one other agent", agent)
    if not named:
        rest = [i for i in range(len(norm.ids)) if i != subject]
        if len(rest) != 1:
            return _not_read(f"{kind.value} needs exactly one other agent", agent)
        named = {rest[0]}
    (other,) = named
    if other == subject:
        return _not_read(f"{kind.value} names one agent only; cannot tell which one is asked", agent)
    best = max(decided, key=lambda m: (m.other is not None, m.end - m.start, -m.start))
    distance = _METRES.search(norm.text)
    metres = float(distance.group(1)) if distance else None
    braking = _DECELERATION.search(norm.text)
    deceleration = None
    if braking:
        deceleration = float(braking.group(1)) * (STANDARD_GRAVITY if braking.group(2) == "g" else 1.0)
    words = norm.span(text, best.start, best.end)
    return PromptReading(kind, agent, norm.ids[other], words, metres=metres, deceleration=deceleration)
