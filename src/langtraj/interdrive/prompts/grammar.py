"""A tiny template grammar for phrase tables: enumerate every expansion of a template, or sample one.

Syntax (whitespace is literal text; after expansion runs of whitespace collapse to one space and
the ends are stripped):

- `{a|b|c}`  alternatives: exactly one of `a`, `b`, `c`; an alternative may be empty (`{a|}`).
- `[x]`      an optional part: nothing, or `x` (in that order, so the first expansion omits it).
- `<name>`   a slot (`name`: letters, digits, `_`, not starting with a digit), kept verbatim as
             `<name>` in the output; callers fill it in (e.g. `<other>` for the other agent).
- `\\c`       the character `c` taken literally (to write `{`, `}`, `[`, `]`, `|`, `<`, `>` or `\\`).

Groups nest freely: `{speeds up|accelerates}[ {gradually|steadily}]`. Expansions are listed in a
fixed order (the first alternative of every group first, the leftmost group varying slowest), so the
first expansion is a template's canonical phrase. Malformed templates raise ValueError naming the
template and the 0-based character position.

See docs/interdrive.md.
"""

from __future__ import annotations

import functools
import itertools
import re
from dataclasses import dataclass

import numpy as np

MAX_EXPANSIONS = 100_000
"""Refuse templates with more raw expansions than this (before de-duplication): a guard against typos."""

_SLOT_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


@dataclass(frozen=True)
class _Seq:
    """A sequence of parts expanded one after another: literal strings and `_Alt` groups."""

    parts: tuple[str | _Alt, ...]


@dataclass(frozen=True)
class _Alt:
    """A choice of exactly one option."""

    options: tuple[_Seq, ...]


class _Parser:
    """Recursive-descent parser of one template into a `_Seq`."""

    def __init__(self, template: str):
        self.text = template
        self.pos = 0

    def error(self, message: str, pos: int | None = None) -> ValueError:
        where = self.pos if pos is None else pos
        return ValueError(f"template {self.text!r}: {message} at position {where}")

    def parse(self) -> _Seq:
        seq = self.sequence(closers="")
        if self.pos < len(self.text):  # only a stray closer or `|` stops the top-level sequence
            raise self.error(f"unexpected {self.text[self.pos]!r}")
        return seq

    def sequence(self, closers: str) -> _Seq:
        parts: list[str | _Alt] = []
        literal: list[str] = []

        def flush() -> None:
            if literal:
                parts.append("".join(literal))
                literal.clear()

        while self.pos < len(self.text):
            char = self.text[self.pos]
            if char in closers or char in "}]|":
                if char not in closers:
                    raise self.error(f"unexpected {char!r}")
                break
            if char == "\\":
                if self.pos + 1 >= len(self.text):
                    raise self.error("dangling escape '\\'")
                literal.append(self.text[self.pos + 1])
                self.pos += 2
            elif char == "{":
                flush()
                parts.append(self.alternatives())
            elif char == "[":
                flush()
                parts.append(self.optional())
            elif char == "<":
                literal.append(self.slot())
            elif char == ">":
                raise self.error("unexpected '>' outside a slot")
            else:
                literal.append(char)
                self.pos += 1
        flush()
        return _Seq(tuple(parts))

    def alternatives(self) -> _Alt:
        start = self.pos
        self.pos += 1  # '{'
        options = [self.sequence(closers="|}")]
        while self.pos < len(self.text) and self.text[self.pos] == "|":
            self.pos += 1
            options.append(self.sequence(closers="|}"))
        if self.pos >= len(self.text):
            raise self.error("unclosed '{'", start)
        self.pos += 1  # '}'
        return _Alt(tuple(options))

    def optional(self) -> _Alt:
        start = self.pos
        self.pos += 1  # '['
        inner = self.sequence(closers="]")
        if self.pos >= len(self.text):
            raise self.error("unclosed '['", start)
        self.pos += 1  # ']'
        return _Alt((_Seq(()), inner))

    def slot(self) -> str:
        start = self.pos
        end = self.text.find(">", start)
        if end < 0:
            raise self.error("unclosed '<'", start)
        name = self.text[start + 1 : end]
        if not _SLOT_NAME.fullmatch(name):
            raise self.error(f"bad slot name {name!r}", start)
        self.pos = end + 1
        return f"<{name}>"


def _count(node: _Seq | _Alt) -> int:
    if isinstance(node, _Alt):
        return sum(_count(o) for o in node.options)
    total = 1
    for part in node.parts:
        if isinstance(part, _Alt):
            total *= _count(part)
    return total


def _expand(node: _Seq | _Alt) -> list[str]:
    if isinstance(node, _Alt):
        return [text for option in node.options for text in _expand(option)]
    choices = [[part] if isinstance(part, str) else _expand(part) for part in node.parts]
    return ["".join(combo) for combo in itertools.product(*choices)]


def normalize(text: str) -> str:
    """Collapse whitespace runs to one space, strip the ends and drop spaces before punctuation."""
    return re.sub(r" ([,.;:!?])", r"\1", " ".join(text.split()))


def parse(template: str) -> _Seq:
    """Parse `template`; raise ValueError naming it and the position when it is malformed."""
    return _Parser(template).parse()


@functools.lru_cache(maxsize=4096)
def _expand_cached(template: str) -> tuple[str, ...]:
    tree = parse(template)
    total = _count(tree)
    if total > MAX_EXPANSIONS:
        raise ValueError(f"template {template!r}: {total} expansions, more than the limit {MAX_EXPANSIONS}")
    return tuple(dict.fromkeys(text for text in map(normalize, _expand(tree)) if text))


def expand(template: str) -> list[str]:
    """Every distinct expansion of `template`, whitespace-normalised, empty ones dropped, in the
    grammar's fixed order (the first is the canonical phrase)."""
    return list(_expand_cached(template))


def expand_all(templates: tuple[str, ...] | list[str]) -> list[str]:
    """The distinct expansions of several templates, in order (a phrase table's entries)."""
    return list(dict.fromkeys(text for template in templates for text in _expand_cached(template)))


def sample(template: str, rng: np.random.Generator) -> str:
    """One expansion of `template` drawn uniformly over its distinct expansions with `rng`."""
    options = _expand_cached(template)
    if not options:
        raise ValueError(f"template {template!r} expands to nothing")
    return options[int(rng.integers(len(options)))]
