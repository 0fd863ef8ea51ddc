"""Counterfactual prompts: the behaviours the map lets an agent do instead of what it did in the log.

The behaviour kinds are those of `interdrive.behaviour`; whether an agent can do one is `interdrive.targets`'
(a behaviour is feasible exactly when the map gives it a target, and says "undecided" where the map lacks what
that needs, never guessing). `feasible_alternatives` turns the feasible single-agent behaviours, and going first or
yielding in each interaction pair the log shows, into prompts, marking those the log itself shows (ground-truth
prompts).
The hand-written free-text prompts (`FreeTextPrompt`, `load_free_text_prompts`) are in `free_text`.

See docs/interdrive.md ('Counterfactual prompts and instruction following').
"""

from __future__ import annotations

from dataclasses import dataclass

from langtraj.interdrive.adherence import AdherenceChecker, Fact
from langtraj.interdrive.behaviour import (
    BEHAVIOURS,
    Behaviour,
    behaviour_facts,
    opposite_subtype,
)
from langtraj.interdrive.dataset import PromptEntry
from langtraj.interdrive.prompts import Prompt, mentions_in
from langtraj.interdrive.targets import CounterfactualConfig, behaviour_feasibility, feasibility
from langtraj.roads import MapIndex
from langtraj.scenario.model import Scenario
from langtraj.scenario.types import AgentType

# ---------------------------------------------------------------------------------------------- alternatives


@dataclass(frozen=True)
class Alternative:
    """A prompt for `track_id` asking for `behaviour` (toward `other_id` for a pair behaviour): the prompt entry
    the model is conditioned on, the facts that judge it, and whether the log shows it (`logged`: a ground-truth
    prompt; otherwise a counterfactual one)."""

    track_id: int
    behaviour: Behaviour
    prompt: PromptEntry
    facts: frozenset[Fact]
    logged: bool
    other_id: int | None = None


def make_alternative(
    behaviour: Behaviour,
    track_id: int,
    logged: frozenset[Fact],
    other_id: int | None = None,
    subtype: str | None = None,
) -> Alternative:
    """The prompt asking `track_id` for `behaviour`, marked as logged when `logged` holds all its facts."""
    spec = BEHAVIOURS[behaviour]
    facts = behaviour_facts(behaviour, track_id, other_id, subtype)
    text = spec.text(track_id, other_id)
    subtype_id = next(iter(facts))[3] if spec.is_pair else None  # type: ignore[misc]
    labels = spec.label_keys
    entry = PromptEntry.of(Prompt(text, mentions_in(text), subtype_id, labels, source="counterfactual"))
    return Alternative(track_id, behaviour, entry, facts, facts <= logged, other_id)


def logged_facts(
    scenario: Scenario, map_index: MapIndex, config: CounterfactualConfig | None = None
) -> frozenset[Fact]:
    """The facts the labelers find on the scene's logged future (what a ground-truth prompt states)."""
    config = config or CounterfactualConfig()
    return AdherenceChecker.build(scenario, config.heuristics, config.detector, map_index).logged


def feasible_alternatives(
    scenario: Scenario,
    track_id: int,
    map_index: MapIndex,
    config: CounterfactualConfig | None = None,
    *,
    logged: frozenset[Fact] | None = None,
) -> tuple[Alternative, ...]:
    """Every prompt `track_id` can follow here: each feasible single-agent behaviour (`behaviour_feasibility`),
    each single-agent behaviour the log shows (the log proves it feasible, also where the map cannot tell), and,
    for each interaction of `PAIR_SUBTYPES` the log shows between it and another agent, both going first and
    yielding, unless the order is out of reach (`targets.feasibility`: going first where the other agent
    gets to the crossing first however the agent speeds up, or a pedestrian is already crossing there). `logged`
    is the log's facts (`logged_facts`, computed when not given; pass them to label the scene once for all its
    agents, or add facts such as ground-truth interactions)."""
    config = config or CounterfactualConfig()
    if logged is None:
        logged = logged_facts(scenario, map_index, config)
    feasible = behaviour_feasibility(scenario, track_id, map_index, config)
    out = []
    for behaviour, verdict in feasible.items():
        alternative = make_alternative(behaviour, track_id, logged)
        if verdict.status == "feasible" or alternative.logged:
            out.append(alternative)
    agent_type = AgentType(int(scenario.agents.types[scenario.agents.index_of(track_id)]))
    pairs: dict[int, dict[Behaviour, str]] = {}
    for fact in sorted(f for f in logged if f[0] == "interaction" and f[1] == track_id):
        other, subtype = int(fact[2]), str(fact[3])
        opposite = opposite_subtype(subtype, agent_type)
        if opposite is None:
            continue
        found = Behaviour.YIELD if subtype.startswith("yielding/") else Behaviour.GO_FIRST
        flipped = Behaviour.GO_FIRST if found is Behaviour.YIELD else Behaviour.YIELD
        pairs.setdefault(other, {}).setdefault(found, subtype)
        pairs[other].setdefault(flipped, opposite)
    for other, chosen in pairs.items():
        for behaviour in (Behaviour.GO_FIRST, Behaviour.YIELD):
            alternative = make_alternative(behaviour, track_id, logged, other, chosen[behaviour])
            verdict = feasibility(scenario, track_id, behaviour, map_index, other_id=other, config=config)
            if alternative.logged or verdict.status != "infeasible":
                out.append(alternative)
    return tuple(out)
