"""InterDrive prompts: phrase tables written in a small template grammar, compositional prompts with
role rephrasing, validated user prompts, per-window prompt pools and an optional LLM rephraser.
See docs/interdrive.md."""

from langtraj.interdrive.prompts.compose import Prompt, compose_prompt, mentions_in, role_rephrase
from langtraj.interdrive.prompts.grammar import expand, sample
from langtraj.interdrive.prompts.llm import LLMConfig, LLMError, LLMRephraser, llm_phrase_bank
from langtraj.interdrive.prompts.phrases import (
    CANONICAL,
    TEMPLATES_ONLY,
    PhraseBank,
    interaction_phrases,
    label_phrases,
    label_variants,
    phrase_key,
    phrase_tables,
)
from langtraj.interdrive.prompts.pool import build_prompt_pool
from langtraj.interdrive.prompts.user import MAX_PROMPT_CHARS, parse_user_prompt

__all__ = [
    "CANONICAL",
    "MAX_PROMPT_CHARS",
    "TEMPLATES_ONLY",
    "LLMConfig",
    "LLMError",
    "LLMRephraser",
    "PhraseBank",
    "Prompt",
    "build_prompt_pool",
    "compose_prompt",
    "expand",
    "interaction_phrases",
    "label_phrases",
    "label_variants",
    "llm_phrase_bank",
    "mentions_in",
    "parse_user_prompt",
    "phrase_key",
    "phrase_tables",
    "role_rephrase",
    "sample",
]
