"""Prompts typed by users, naming agents by track id (`@12 yields to @7 at the intersection`), validated
so that a bad prompt fails with one clear message instead of conditioning the model on junk. See docs/interdrive.md."""

from __future__ import annotations

import functools
import re
import unicodedata
from collections.abc import Iterable
from dataclasses import replace

from langtraj.errors import InputError
from langtraj.interdrive.prompts.compose import MENTION, Prompt, mentions_in
from langtraj.interdrive.prompts.phrases import OTHER_SLOT

_AT_TOKEN = re.compile(r"@\S*")
_WORD = re.compile(r"[^\W\d_]+")
_JUNK_WORDS = frozenset({"nan", "none", "null", "inf", "infinity", "undefined"})
_ALLOWED_CONTROLS = "\t\n\r"  # typed whitespace; normalised to single spaces
_SHOWN_IDS = 10


def _describe_ids(ids: list[int]) -> str:
    if not ids:
        return "the scene has no agents"
    shown = ", ".join(map(str, ids[:_SHOWN_IDS]))
    more = f", ... ({len(ids)} in all)" if len(ids) > _SHOWN_IDS else ""
    return f"the scene has agents {shown}{more}"


def _check_characters(text: str) -> None:
    for pos, char in enumerate(text):
        if char not in _ALLOWED_CONTROLS and unicodedata.category(char).startswith("C"):
            raise InputError(f"prompt has a control or invisible character {char!r} at position {pos}")


def _check_mentions(text: str) -> None:
    """Every `@` must start a well-formed mention `@<digits>`."""
    valid = {m.start() for m in MENTION.finditer(text)}
    for token in _AT_TOKEN.finditer(text):
        if token.start() not in valid:
            raise InputError(
                f"malformed agent mention {token.group()!r} at position {token.start()}; write agents as @<track id>,"
                " e.g. @12"
            )


MAX_PROMPT_CHARS = 300
"""The longest typed prompt accepted (characters): longer ones are refused before anything reads them."""


def parse_user_prompt(text: str, track_ids: Iterable[int], max_chars: int = MAX_PROMPT_CHARS) -> Prompt:
    """Validate a typed prompt against the scene's `track_ids` and return it as a Prompt (source "user");
    empty, overlong, mention-less, junk or malformed prompts and unknown ids raise InputError."""
    if not isinstance(text, str):
        raise InputError(f"prompt must be a string, got {type(text).__name__}")
    if not text.strip():
        raise InputError("empty prompt")
    if len(text) > max_chars:
        raise InputError(f"prompt is {len(text)} characters long; the limit is {max_chars}")
    _check_characters(text)
    text = " ".join(text.split())
    _check_mentions(text)
    mentions = mentions_in(text)
    if not mentions:
        raise InputError("prompt mentions no agent; name agents by track id, e.g. '@12 yields to @7'")
    words = [w.lower() for w in _WORD.findall(MENTION.sub(" ", text))]
    if not words or all(w in _JUNK_WORDS for w in words):
        raise InputError(f"prompt {text!r} describes no behaviour")
    known = sorted({int(t) for t in track_ids})
    unknown = [m for m in mentions if m not in set(known)]
    if unknown:
        named = ", ".join(f"@{m}" for m in unknown)
        raise InputError(f"unknown agent{'s' if len(unknown) > 1 else ''} {named}; {_describe_ids(known)}")
    text = MENTION.sub(lambda m: f"@{int(m.group(1))}", text)  # "@007" -> "@7"
    return Prompt(text=text, mentions=mentions, source="user")


@functools.cache
def _phrase_patterns() -> tuple[tuple[str, bool, re.Pattern[str]], ...]:
    """(label key or subtype id, is a subtype, pattern) for every template phrase, longest phrase first."""
    from langtraj.interdrive.prompts.phrases import phrase_tables
    from langtraj.interdrive.taxonomy import SUBTYPES_BY_ID

    found = []
    for order, (key, phrases) in enumerate(phrase_tables().items()):
        subtype = key in SUBTYPES_BY_ID
        forms = set(phrases)
        if subtype:  # "yields to <other>" also names the subtype of "yields to <other> at the intersection"
            forms |= {p[: p.index(OTHER_SLOT) + len(OTHER_SLOT)] for p in phrases if OTHER_SLOT in p}
        for phrase in sorted(forms):
            words = re.escape(phrase.lower()).replace(re.escape(OTHER_SLOT), r"@\d+")
            found.append((len(phrase), order, key.split("[")[0], subtype, re.compile(rf"(?<![\w<]){words}(?!\w)")))
    found.sort(key=lambda item: (-item[0], item[1]))  # longest first; ties in taxonomy order
    return tuple((key, subtype, pattern) for _, _, key, subtype, pattern in found)


def recognize_prompt(prompt: Prompt) -> Prompt:
    """The prompt with the interaction subtype and single-agent labels its text states, read back from the
    phrase tables (the inverse of composing a prompt): the longest interaction phrase (or its part up to
    the other agent) gives the subtype, every other non-overlapping label phrase a label key. Phrases are
    matched case-insensitively as written in `phrases.py`; a prompt in other words gains nothing."""
    text = prompt.text.lower()
    taken = [False] * len(text)
    subtype: str | None = None
    labels: list[str] = []
    for key, is_subtype, pattern in _phrase_patterns():
        if is_subtype and subtype is not None:
            continue
        for match in pattern.finditer(text):
            if any(taken[match.start() : match.end()]):
                continue
            taken[match.start() : match.end()] = [True] * (match.end() - match.start())
            if is_subtype:
                subtype = key
            elif key not in labels:
                labels.append(key)
            break
    return replace(prompt, subtype_id=prompt.subtype_id or subtype, label_keys=prompt.label_keys or tuple(labels))
