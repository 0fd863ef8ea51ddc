"""The prompt reader's words: every inflection of a verb (`verb`), and the word classes the behaviours' phrases
share (the other agent `OTHER`, a request's object `OBJ`, a few words within a clause `gap`, ...). Each behaviour's
own phrases are in its module of `interdrive.behaviours` (`BehaviourKind.words`). The patterns run over the normalised
text of `read.py`, where each `@id` mention is a placeholder `<m0>`, `<m1>`, ...; a named group `other` marks the
other agent of a pair kind and `agent` the agent a request names as its object.

See docs/interdrive.md ('Reading a prompt').
"""

from __future__ import annotations

import re

SLOT = r"<m\d+>"
VEHICLE = (
    r"(?:car|truck|lorry|van|bus|coach|vehicle|cyclist|bike|bicycle|pedestrian|motorbike|motorcycle|scooter|taxi|cab"
    r"|suv|sedan|person|walker|driver|agent|one|tractor|trailer)"
)
APPOSITION = rf"(?:(?:the|a|an|that|this)\s+(?:[\w-]+\s+){{0,2}}?{VEHICLE}\s*,?\s+)"
"""A noun phrase naming the other agent before its mention: "follows the lorry, @7", "behind the truck @7"."""
OTHER = rf"{APPOSITION}?(?P<other>{SLOT})"
OBJ = rf"(?:\s+(?P<agent>{SLOT}))?"
"""The asked agent as the object of a request: "move @12 one lane to the left", "bring @12 to a halt"."""
PLACEHOLDER = re.compile(r"<m(\d+)>")

# ---------------------------------------------------------------------------------------------- words

_IRREGULAR: dict[str, tuple[str, ...]] = {
    "go": ("goes", "going", "went", "gone"),
    "take": ("takes", "taking", "took", "taken"),
    "make": ("makes", "making", "made"),
    "come": ("comes", "coming", "came"),
    "get": ("gets", "getting", "got", "gotten"),
    "hang": ("hangs", "hanging", "hung"),
    "let": ("lets", "letting"),
    "cut": ("cuts", "cutting"),
    "put": ("puts", "putting"),
    "hold": ("holds", "holding", "held"),
    "keep": ("keeps", "keeping", "kept"),
    "bring": ("brings", "bringing", "brought"),
    "give": ("gives", "giving", "gave", "given"),
    "lose": ("loses", "losing", "lost"),
    "slide": ("slides", "sliding", "slid"),
    "swing": ("swings", "swinging", "swung"),
    "drive": ("drives", "driving", "drove", "driven"),
    "ride": ("rides", "riding", "rode", "ridden"),
    "run": ("runs", "running", "ran"),
    "stand": ("stands", "standing", "stood"),
    "sit": ("sits", "sitting", "sat"),
    "beat": ("beats", "beating", "beaten"),
    "bear": ("bears", "bearing", "bore", "borne"),
    "freeze": ("freezes", "freezing", "froze", "frozen"),
    "draw": ("draws", "drawing", "drew", "drawn"),
    "speed": ("speeds", "speeding", "sped"),
    "fall": ("falls", "falling", "fell", "fallen"),
    "shoot": ("shoots", "shooting", "shot"),
    "leave": ("leaves", "leaving"),  # not "left": that is a side
    "grind": ("grinds", "grinding", "ground"),
    "have": ("has", "having", "had"),
    "do": ("does", "doing", "did", "done"),
    "shed": ("sheds", "shedding"),
    "set": ("sets", "setting"),
    "hit": ("hits", "hitting"),
    "see": ("sees", "seeing", "saw", "seen"),
}
_DOUBLED = frozenset(
    {"stop", "nip", "hop", "slip", "step", "drop", "pop", "swap", "slot", "tag", "tap", "gun", "permit", "submit"}
)
"""Verbs doubling their last consonant: stopping, stopped."""


def _forms(base: str) -> tuple[str, ...]:
    """The base, third-person, -ing and past forms of a regular or listed irregular verb."""
    if base in _IRREGULAR:
        return (base, *_IRREGULAR[base])
    consonant_y = base.endswith("y") and base[-2] not in "aeiou"
    if base.endswith(("s", "sh", "ch", "x", "z")):
        third = base + "es"
    else:
        third = base[:-1] + "ies" if consonant_y else base + "s"
    if base in _DOUBLED:
        stem = base + base[-1]
    else:
        stem = base[:-1] if base.endswith("e") and not base.endswith("ee") else base
    past = base + "d" if base.endswith("e") else (base[:-1] + "ied" if consonant_y else stem + "ed")
    if base.endswith("el"):  # travel: British travelling, travelled beside traveling, traveled
        return base, third, stem + "ing", past, base + "ling", base + "led"
    return base, third, stem + "ing", past


def verb(*bases: str) -> str:
    """A non-capturing group of every form of `bases` (a multi-word base inflects its first word)."""
    forms: set[str] = set()
    for base in bases:
        head, _, tail = base.partition(" ")
        forms.update(f"{form} {tail}".strip() for form in _forms(head))
    return "(?:" + "|".join(sorted((re.escape(f).replace(r"\ ", r"\s+") for f in forms), key=len, reverse=True)) + ")"


def gap(words: int) -> str:
    """Up to `words` words within one clause (not across 'and', 'then', 'but', 'or' or punctuation)."""
    return rf"(?:\s+(?!(?:and|then|but|or)\b)[\w'<>-]+){{0,{words}}}?"


TIGHT_GAP = r"(?:(?!\b(?:and|then|but|or)\b)[^,;.!?]){0,40}?"
"""Up to 40 characters within one clause."""

POSSESSIVE = r"(?:the|its|your|their|his|her|one's)"

IN_FRONT = r"(?:(?:right|just|directly|immediately)\s+)?(?:in\s+front\s+of|ahead\s+of)"
"""Just ahead of someone: "in front of", "right ahead of"."""
