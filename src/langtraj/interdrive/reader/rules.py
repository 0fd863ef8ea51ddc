"""The prompt reader's rules: the rule table (every behaviour's phrases, `BehaviourKind.words`, in their
`word_rank` order), the kinds one kind subsumes and those that may follow it in one clause (`tables()`), gathered
from the behaviours' registry (`interdrive.behaviours.KINDS`) when asked; and the
negation, 'instead of' and passive patterns that stop a reading. The word classes are `words.py`'s.

See docs/interdrive.md ('Reading a prompt').
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import cache

from langtraj.interdrive.behaviour import Behaviour, names
from langtraj.interdrive.reader.words import OBJ, OTHER, PLACEHOLDER, SLOT, verb

__all__ = ["CONTRAST", "NEGATION", "OBJ", "OTHER", "PASSIVE", "PLACEHOLDER", "SLOT", "Rule", "tables", "verb"]


@dataclass(frozen=True)
class Rule:
    """One phrase of a behaviour: the kind and its compiled pattern."""

    behaviour: Behaviour
    pattern: re.Pattern[str]


@cache
def _tables(
    names: tuple[str, ...],
) -> tuple[tuple[Rule, ...], dict[Behaviour, frozenset[Behaviour]], dict[Behaviour, frozenset[Behaviour]]]:
    """The rule table, the kinds each subsumes and those that may follow each of the behaviours `names` (the
    registry's, in its order)."""
    from langtraj.interdrive.behaviours import kind

    kinds = [kind(n) for n in names]
    ranked = sorted(range(len(kinds)), key=lambda i: (kinds[i].word_rank, i))
    rules = tuple(Rule(Behaviour(kinds[i].name), re.compile(p)) for i in ranked for p in kinds[i].words)
    subsumes = {Behaviour(k.name): frozenset(map(Behaviour, k.subsumes)) for k in kinds if k.subsumes}
    then = {Behaviour(k.name): frozenset(map(Behaviour, k.then)) for k in kinds if k.then}
    return rules, subsumes, then


def tables() -> tuple[tuple[Rule, ...], dict[Behaviour, frozenset[Behaviour]], dict[Behaviour, frozenset[Behaviour]]]:
    """(rules, subsumes, then) as the registry holds now (a behaviour registered later joins them)."""
    return _tables(names())


NEGATION = re.compile(
    r"\b(?:not|never|no\s+longer|without|neither|nor|cannot|no|refuses?\s+to|refusing\s+to|fails?\s+to"
    r"|avoid(?:s|ing)?)\b|n't\b"
)
CONTRAST = re.compile(r"\b(?:instead\s+of|rather\s+than)\b[^,;.!?]*")
"""What follows 'instead of' in its clause is what the prompt does not ask ("goes straight instead of turning")."""
PASSIVE = re.compile(rf"\b(?:is|are|was|were|be|been|being|gets?|got)\b[^,;.!?]*?\bby\s+{SLOT}")
"""A passive clause naming an agent ("@7 is followed by @12"): who does what is not read."""
