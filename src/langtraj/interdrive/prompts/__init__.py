"""InterDrive prompts: phrase tables written in a small template grammar, compositional prompts with
role rephrasing, validated user prompts, per-window prompt pools and an optional LLM rephraser."""

from langtraj.interdrive.prompts.compose import Prompt, compose_prompt, mentions_in, role_rephrase
from langtraj.interdrive.prompts.grammar import expand, sample
from langtraj.interdrive.prompts.llm import LLMConfig, LLMError, LLMRephraser
from langtraj.interdrive.prompts.phrases import (
    CANONICAL,
    interaction_phrases,
    label_phrases,
    label_variants,
    phrase_key,
)
from langtraj.interdrive.prompts.pool import build_prompt_pool
from langtraj.interdrive.prompts.user import parse_user_prompt

__all__ = [
    "CANONICAL",
    "LLMConfig",
    "LLMError",
    "LLMRephraser",
    "Prompt",
    "build_prompt_pool",
    "compose_prompt",
    "expand",
    "interaction_phrases",
    "label_phrases",
    "label_variants",
    "mentions_in",
    "parse_user_prompt",
    "phrase_key",
    "role_rephrase",
    "sample",
]
