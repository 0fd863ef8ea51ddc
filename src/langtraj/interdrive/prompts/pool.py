"""The prompt pool of one window: a few distinct compositional prompts per labelled agent, drawn
deterministically from a seed, to train and evaluate language conditioning. See docs/interdrive.md."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from langtraj.errors import InputError
from langtraj.interdrive.labels import AgentLabel, InteractionLabel, WindowLabels
from langtraj.interdrive.prompts.compose import Prompt, compose_prompt
from langtraj.interdrive.prompts.phrases import TEMPLATES_ONLY, PhraseBank

SKIPPED_SUBTYPES = frozenset({"other/unknown"})
"""Interactions that say nothing usable: never turned into prompts."""

MAX_LABELS_PER_PROMPT = 3
_ATTEMPTS_PER_PROMPT = 10  # draws tried per wanted prompt before giving up on distinctness


def _subset(labels: Sequence[AgentLabel], rng: np.random.Generator, at_least: int) -> list[AgentLabel]:
    """A random subset of `labels` of size at_least..3 (fewer when there are fewer labels)."""
    most = min(MAX_LABELS_PER_PROMPT, len(labels))
    size = int(rng.integers(min(at_least, most), most + 1))
    picked = sorted(rng.choice(len(labels), size=size, replace=False).tolist()) if size else []
    return [labels[i] for i in picked]


def _agent_prompts(
    track_id: int,
    interactions: Sequence[InteractionLabel],
    labels: Sequence[AgentLabel],
    rng: np.random.Generator,
    per_agent: int,
    bank: PhraseBank,
) -> list[Prompt]:
    order = rng.permutation(len(interactions)).tolist() if interactions else []
    made: dict[str, Prompt] = {}
    for attempt in range(per_agent * _ATTEMPTS_PER_PROMPT):
        if len(made) == per_agent:
            break
        if interactions:  # cycle through the interactions so each is used before any repeats
            interaction = interactions[order[attempt % len(order)]]
            subset = _subset(labels, rng, at_least=0) if labels else []
        else:
            interaction, subset = None, _subset(labels, rng, at_least=1)
        prompt = compose_prompt(track_id, interaction, subset, rng, MAX_LABELS_PER_PROMPT, bank)
        made.setdefault(prompt.text, prompt)
    return list(made.values())


def build_prompt_pool(
    labels: WindowLabels, seed: int, per_agent: int = 3, bank: PhraseBank = TEMPLATES_ONLY
) -> tuple[Prompt, ...]:
    """Up to `per_agent` distinct prompts for every agent with interactions or single-agent labels, in
    order of track id: each interaction combined with a random 0-3 of the agent's labels, or 1-3 labels
    alone for agents without interactions; `other/unknown` interactions are skipped. Phrases come from `bank`.
    Deterministic in `seed`."""
    if per_agent < 1:
        raise InputError(f"per_agent must be >= 1, got {per_agent}")
    rng = np.random.default_rng(seed)
    usable = [i for i in labels.interactions if i.subtype.id not in SKIPPED_SUBTYPES]
    track_ids = sorted({lab.track_id for lab in labels.agent_labels} | {i.track_id for i in usable})
    pool: list[Prompt] = []
    for track_id in track_ids:
        interactions = [i for i in usable if i.track_id == track_id]
        pool += _agent_prompts(track_id, interactions, labels.labels_of(track_id), rng, per_agent, bank)
    return tuple(pool)
