"""Typed `@id` prompts in a simulation: parsed against the scene, merged into one prompt entry, checked
against the agents the model drives and against the map (a turn or lane change it does not allow is warned
about), and turned into each driven agent's sentence (docs/simulation.md)."""

from __future__ import annotations

from collections.abc import Sequence

from langtraj.errors import InputError
from langtraj.interdrive.counterfactual import infeasible_manoeuvres
from langtraj.interdrive.dataset import PromptEntry
from langtraj.interdrive.mapindex import MapIndex
from langtraj.interdrive.prompts import parse_user_prompt
from langtraj.scenario.model import Scenario


def user_prompt_entry(scenario: Scenario, text: str) -> PromptEntry:
    """A typed `@id` prompt validated against the scene and role-rephrased for each mentioned agent."""
    prompt = parse_user_prompt(text, scenario.agents.ids.tolist())
    return PromptEntry.of(prompt)


def merged_prompt(scenario: Scenario, prompts: Sequence[str]) -> PromptEntry | None:
    """One prompt entry from several typed prompts; an agent named by two prompts is an error."""
    entries = [user_prompt_entry(scenario, text) for text in prompts]
    if not entries:
        return None
    if len(entries) == 1:
        return entries[0]
    roles: dict[int, str] = {}
    for entry in entries:
        for track in entry.mentions:
            if track in roles:
                raise InputError(f"agent @{track} is named by two prompts; describe it in one", where="prompt")
            roles[track] = entry.roles[track]
    return PromptEntry("; ".join(e.text for e in entries), tuple(roles), roles, None, (), "user")


def check_prompt_driven(prompt: PromptEntry, driven_ids: Sequence[int], max_driven: int | None) -> None:
    """InputError naming the prompt's agents that are not among `driven_ids` (the model's agents: every
    sim agent, or the `max_driven` most important)."""
    outside = [m for m in prompt.mentions if m not in set(driven_ids)]
    if outside:
        which = (
            f"it drives the {max_driven} most important (--max-driven)"
            if max_driven is not None
            else "it drives the agents valid at the current step"
        )
        raise InputError(
            f"agents {', '.join(f'@{m}' for m in outside)} are not among the {len(driven_ids)} agents the model "
            f"drives in this scene ({which})",
            where="prompt",
        )


def prompt_warnings(scenario: Scenario, prompts: Sequence[str]) -> list[str]:
    """One line per turn or lane change a typed prompt asks of its target agent that the map does not allow
    there ("@12 cannot turn left: no left turn from its lane at the next junction ..."); empty without prompts.
    A warning does not stop a simulation: the model is conditioned on the prompt as typed."""
    if not prompts:
        return []
    index = MapIndex.build(scenario.road_map)
    return [
        warning.message
        for text in prompts
        for warning in infeasible_manoeuvres(scenario, user_prompt_entry(scenario, text), index)
    ]
