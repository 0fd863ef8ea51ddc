"""Compositional prompts: an interaction description joined with single-agent labels, and role rephrasing.

A prompt names agents with `@<track_id>` tokens ("@12 yields to @7 at the intersection, then speeds up
and turns left"). The model is conditioned per agent: `role_rephrase` writes, for each mentioned agent,
the sentence in which it is "the target agent" and the others are "other agent1", "other agent2", ...
(paper, section 'LangTraj'); agents the prompt does not mention get no sentence (the null condition).

See docs/interdrive.md.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from langtraj.errors import InputError
from langtraj.interdrive.labels import AgentLabel, InteractionLabel
from langtraj.interdrive.prompts.phrases import OTHER_FALLBACK, OTHER_SLOT, TEMPLATES_ONLY, PhraseBank

MENTION = re.compile(r"(?<![\w@])@(\d+)(?!\w)")
"""An agent mention `@<track_id>` (not inside a word, not followed by letters or digits)."""

_PROGRESSIVE = re.compile(r"^is \w+ing\b")
_OPEN_ENDED = re.compile(r"\b(?:while|as|because|until|which|who)\b")
"""A phrase ending in a clause about another agent ("... while @7 waits"): a following "and" needs a comma."""

TARGET = "the target agent"
OTHER_PREFIX = "other agent"


def mentions_in(text: str) -> tuple[int, ...]:
    """The track ids mentioned in `text`, in order of first mention."""
    return tuple(dict.fromkeys(int(m.group(1)) for m in MENTION.finditer(text)))


@dataclass(frozen=True)
class Prompt:
    """One language instruction: `text` names agents as `@<track_id>`; `mentions` lists them in order of
    first mention; `subtype_id` and `label_keys` say which labels it expresses; `source` where they came
    from ("ground_truth", "detector", "human", "heuristic" or "user")."""

    text: str
    mentions: tuple[int, ...]
    subtype_id: str | None = None
    label_keys: tuple[str, ...] = ()
    source: str = "heuristic"

    def __post_init__(self) -> None:
        found = mentions_in(self.text)
        if tuple(self.mentions) != found:
            raise ValueError(f"prompt {self.text!r}: mentions {self.mentions} do not match the text's {found}")


@dataclass(frozen=True)
class _Clause:
    """One verb phrase of a prompt and the steps [start, end) it describes."""

    start: int
    end: int
    text: str
    key: str | None  # the label key; None for the interaction

    @property
    def open_ended(self) -> bool:
        return bool(_OPEN_ENDED.search(self.text))


def _pick(options: Sequence[str], rng: np.random.Generator, simple: bool) -> str:
    """One of `options`; with `simple`, one not in the progressive ("is speeding up") where there is one,
    so that joined clauses read "yields to @7, then speeds up" rather than "..., then is speeding up"."""
    if simple:
        options = [o for o in options if not _PROGRESSIVE.match(o)] or options
    return options[int(rng.integers(len(options)))]


def _interaction_clause(
    track_id: int, interaction: InteractionLabel, rng: np.random.Generator, simple: bool, bank: PhraseBank
) -> _Clause:
    if interaction.track_id != track_id:
        raise InputError(f"interaction of track {interaction.track_id} given for track {track_id}")
    if interaction.other_id == track_id:
        raise InputError(f"interaction of track {track_id} names itself as the other agent")
    other = f"@{interaction.other_id}" if interaction.other_id >= 0 else OTHER_FALLBACK
    phrase = _pick(bank.interactions(interaction.subtype.id), rng, simple).replace(OTHER_SLOT, other)
    return _Clause(interaction.start, interaction.end, phrase, None)


def _join_group(group: list[_Clause]) -> str:
    """Join simultaneous clauses as `a`, `a and b`, `a, b and c`; `a while @7 waits, and b` after an open one."""
    text = group[0].text
    for i, clause in enumerate(group[1:], start=1):
        last = i == len(group) - 1
        sep = (", and " if group[i - 1].open_ended else " and ") if last else ", "
        text += sep + clause.text
    return text


def _join(clauses: list[_Clause]) -> str:
    """Clauses in order of start; overlapping ones are joined with "and", later ones with ", then"."""
    groups: list[list[_Clause]] = []
    group_end: int | None = None
    for clause in clauses:
        if group_end is None or clause.start >= group_end:
            groups.append([clause])
            group_end = clause.end
        else:
            groups[-1].append(clause)
            group_end = max(group_end, clause.end)
    return ", then ".join(_join_group(g) for g in groups)


def compose_prompt(
    track_id: int,
    interaction: InteractionLabel | None,
    labels: Sequence[AgentLabel],
    rng: np.random.Generator,
    max_labels: int = 3,
    bank: PhraseBank = TEMPLATES_ONLY,
) -> Prompt:
    """A prompt for `track_id` joining `interaction` (if any) with up to `max_labels` of its single-agent
    `labels` (a random subset when there are more), phrases drawn with `rng` from `bank`, ordered by start step."""
    if max_labels < 0:
        raise InputError(f"max_labels must be >= 0, got {max_labels}")
    for lab in labels:
        if lab.track_id != track_id:
            raise InputError(f"label {lab.key!r} of track {lab.track_id} given for track {track_id}")
    chosen = list(labels)
    if len(chosen) > max_labels:
        keep = sorted(rng.choice(len(chosen), size=max_labels, replace=False).tolist())
        chosen = [chosen[i] for i in keep]
    if interaction is None and not chosen:
        raise InputError(f"nothing to describe for track {track_id}: no interaction and no labels")
    simple = len(chosen) + (interaction is not None) > 1
    clauses = [] if interaction is None else [_interaction_clause(track_id, interaction, rng, simple, bank)]
    clauses += [
        _Clause(lab.start, lab.end, _pick(bank.labels(lab.key, lab.params), rng, simple), lab.key) for lab in chosen
    ]
    clauses.sort(key=lambda c: c.start)  # stable: the interaction first among equal starts
    text = f"@{track_id} {_join(clauses)}"
    return Prompt(
        text=text,
        mentions=mentions_in(text),
        subtype_id=None if interaction is None else interaction.subtype.id,
        label_keys=tuple(c.key for c in clauses if c.key is not None),
        source="heuristic" if interaction is None else interaction.source.value,
    )


def role_names(mentions: Sequence[int], target: int) -> dict[int, str]:
    """How each mentioned agent is called when `target` is the target agent."""
    others = [m for m in mentions if m != target]
    return {target: TARGET, **{m: f"{OTHER_PREFIX}{i}" for i, m in enumerate(others, start=1)}}


def role_rephrase(prompt: Prompt) -> dict[int, str]:
    """For each mentioned agent (in order of first mention), the prompt rewritten with it as "the target
    agent" and the others as "other agent1", "other agent2", ... in order of first mention."""
    out: dict[int, str] = {}
    for target in prompt.mentions:
        names = role_names(prompt.mentions, target)
        out[target] = MENTION.sub(lambda m, names=names: names[int(m.group(1))], prompt.text)
    return out
