"""Prompts typed by users, naming agents by track id (`@12 yields to @7 at the intersection`), validated
so that a bad prompt fails with one clear message instead of conditioning the model on junk."""

from __future__ import annotations

import re
import unicodedata
from collections.abc import Iterable

from langtraj.errors import InputError
from langtraj.interdrive.prompts.compose import MENTION, Prompt, mentions_in

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


def parse_user_prompt(text: str, track_ids: Iterable[int], max_chars: int = 300) -> Prompt:
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
