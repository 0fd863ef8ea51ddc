"""Hand-written free-text prompts outside the template grammar: `FreeTextPrompt` and `load_free_text_prompts`
(docs/interdrive.md, 'Counterfactual prompts and instruction following')."""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import yaml

from langtraj.errors import InputError
from langtraj.interdrive.adherence import Fact
from langtraj.interdrive.behaviour import BEHAVIOURS, Behaviour, behaviour_facts
from langtraj.interdrive.dataset import PromptEntry
from langtraj.interdrive.prompts import Prompt, parse_user_prompt


@dataclass(frozen=True)
class FreeTextPrompt:
    """A hand-written prompt outside the template grammar: `text` names the agent `{agent}` (and `{other}`),
    `behaviour` is what it asks for."""

    text: str
    behaviour: Behaviour

    @property
    def needs_other(self) -> bool:
        return "{other}" in self.text

    def render(self, agent: int, other: int | None = None) -> str:
        """The `@id` prompt for `agent` (and `other`)."""
        if self.needs_other and other is None:
            raise InputError(f"free-text prompt {self.text!r} needs another agent")
        return self.text.replace("{agent}", f"@{agent}").replace("{other}", f"@{other}")

    def entry(self, agent: int, other: int | None = None) -> tuple[PromptEntry, frozenset[Fact]]:
        """The validated prompt entry (labelled with the behaviour's label or subtype) and the facts judging it."""
        text = self.render(agent, other)
        ids = [agent] if other is None else [agent, other]
        facts = behaviour_facts(self.behaviour, agent, other if self.needs_other else None)
        spec = BEHAVIOURS[self.behaviour]
        subtype = next(iter(facts))[3] if spec.is_pair else None  # type: ignore[misc]
        labels = spec.label_keys
        parsed = parse_user_prompt(text, ids)
        return PromptEntry.of(Prompt(parsed.text, parsed.mentions, subtype, labels, source="user")), facts


def load_free_text_prompts(path: str | Path) -> tuple[FreeTextPrompt, ...]:
    """Free-text prompts from a YAML or JSON list of `{text, behaviour}` entries; a bad entry raises InputError
    naming it (an unknown behaviour, no `{agent}`, an `{other}` a single-agent behaviour does not take, a pair
    behaviour without `{other}`)."""
    path = Path(path)
    try:
        raw = path.read_text()
        data = json.loads(raw) if path.suffix == ".json" else yaml.safe_load(raw)
    except (OSError, ValueError, yaml.YAMLError) as exc:
        raise InputError(f"cannot read free-text prompts: {exc}", path=path) from None
    entries = data.get("prompts") if isinstance(data, Mapping) else data
    if not isinstance(entries, list):
        raise InputError("expected a list of prompts (or a mapping with a 'prompts' list)", path=path)
    return tuple(_free_text(obj, path, f"prompts[{i}]") for i, obj in enumerate(entries))


def _free_text(obj: object, path: Path, where: str) -> FreeTextPrompt:
    if not isinstance(obj, Mapping) or not isinstance(obj.get("text"), str):
        raise InputError("expected a mapping with a string 'text'", path=path, where=where)
    if str(obj.get("behaviour")) not in BEHAVIOURS:
        known = ", ".join(b.value for b in Behaviour)
        raise InputError(f"unknown behaviour {obj.get('behaviour')!r}; known: {known}", path=path, where=where)
    behaviour = Behaviour(str(obj.get("behaviour")))
    prompt = FreeTextPrompt(" ".join(str(obj["text"]).split()), behaviour)
    if "{agent}" not in prompt.text:
        raise InputError("the text names no {agent}", path=path, where=where)
    if prompt.needs_other != BEHAVIOURS[behaviour].is_pair:
        need = "needs" if BEHAVIOURS[behaviour].is_pair else "takes no"
        raise InputError(f"behaviour {behaviour.value!r} {need} {{other}}", path=path, where=where)
    return prompt
