"""Typed `@id` prompts in a simulation: parsed against the scene, merged into one prompt entry, checked
against the agents the model drives and against the map (a turn or lane change it does not allow is warned
about), turned into each driven agent's sentence, and read into the behaviour, target and criteria that steer
the simulation (`prompt_steering`; docs/simulation.md, 'Prompts that steer')."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from langtraj.errors import InputError
from langtraj.frames import Origin
from langtraj.guidance.steering import Steering
from langtraj.interdrive.behaviour import Behaviour
from langtraj.interdrive.counterfactual import infeasible_manoeuvres
from langtraj.interdrive.dataset import PromptEntry
from langtraj.interdrive.mapindex import MapIndex
from langtraj.interdrive.prompts import parse_user_prompt
from langtraj.interdrive.reader import PromptReading, read_prompt
from langtraj.interdrive.targets import BehaviourTarget, TargetUnavailable, derive_target
from langtraj.scenario.model import Scenario
from langtraj.sim.adherence import Ask
from langtraj.sim.config import PromptLevers


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


@dataclass(frozen=True)
class PromptSteering:
    """What typed prompts steer in one simulation: what the reader made of each (`readings`), the guidance toward
    each read behaviour's target (`steerings`, when the guidance lever is on; for yielding or going first also the
    other agent's side of it), what selection judges
    (`asks`, when the selection lever is on), and one line per prompt saying so (`notes`)."""

    readings: tuple[PromptReading, ...] = ()
    steerings: tuple[Steering, ...] = ()
    asks: tuple[Ask, ...] = ()
    notes: tuple[str, ...] = ()
    targets: tuple[BehaviourTarget, ...] = ()

    def to_json(self) -> dict[str, Any]:
        return {
            "read": [r.to_json() for r in self.readings],
            "targets": [t.to_json() for t in self.targets],
            "steering": list(self.notes),
        }


def prompt_steering(
    scenario: Scenario,
    texts: Sequence[str],
    rows: np.ndarray,
    origin: Origin,
    levers: PromptLevers,
    index: MapIndex | None = None,
) -> PromptSteering:
    """Read each typed prompt (`interdrive.reader`), derive its behaviour's target from the map at the current
    step (`interdrive.targets`) and turn it into guidance and selection criteria for the driven agents `rows`
    (scenario rows in slot order). A prompt the reader cannot read, or whose target the map does not give,
    steers by the levers it can (text; selection still judges a read behaviour), and its note says so."""
    slots = {int(scenario.agents.ids[row]): slot for slot, row in enumerate(rows)}
    readings = tuple(read_prompt(text) for text in texts)
    steerings, asks, notes, targets = [], [], [], []
    for reading in readings:
        if reading.behaviour is None or reading.agent is None:
            alone = "it steers by its text alone" if levers.text else "nothing steers it (the text lever is off)"
            notes.append(f"{reading.describe()}; {alone}")
            continue
        if reading.agent not in slots:
            raise InputError(f"@{reading.agent} is not among the agents the model drives", where="prompt")
        other_row = None if reading.other is None else scenario.agents.index_of(reading.other)
        ask = Ask(
            reading.agent,
            scenario.agents.index_of(reading.agent),
            slots[reading.agent],
            reading.behaviour,
            reading.other,
            other_row,
            None if reading.other is None else slots.get(reading.other),
        )
        used = ["text"] if levers.text else []
        if levers.guidance:
            index = index or MapIndex.build(scenario.road_map)
            try:
                target = derive_target(scenario, reading.agent, reading.behaviour, index, other_id=reading.other)
            except TargetUnavailable as exc:
                notes.append(f"{reading.describe()}; no target: {exc.detail}")
            else:
                targets.append(target)
                steerings.append(Steering.of(target, origin, slots))
                used.append(f"guidance toward {target.reason}")
                counterpart, why = _counterpart(scenario, reading, slots, index)
                if counterpart is not None:
                    steerings.append(Steering.of(counterpart, origin, slots))
                    used.append(f"@{counterpart.track_id} toward {counterpart.reason}")
                elif why:
                    used.append(f"@{reading.other} unsteered ({why})")
        if levers.selection:
            asks.append(ask)
            used.append("adherence-first selection")
        notes.append(f"{reading.describe()}; steered by {', '.join(used) or 'nothing'}")
    return PromptSteering(readings, tuple(steerings), tuple(asks), tuple(notes), tuple(targets))


_OPPOSITE = {Behaviour.YIELD: Behaviour.GO_FIRST, Behaviour.GO_FIRST: Behaviour.YIELD}


def _counterpart(
    scenario: Scenario, reading: PromptReading, slots: dict[int, int], index: MapIndex
) -> tuple[BehaviourTarget | None, str]:
    """For yielding or going first, the other agent's side of it (going first, or yielding) when the model drives
    it and the map gives its target (a yield happens only if the other agent goes); else None and why (empty for
    a behaviour without a side for the other agent)."""
    opposite = _OPPOSITE.get(reading.behaviour)  # type: ignore[arg-type]
    if opposite is None or reading.agent is None:
        return None, ""
    if reading.other not in slots:
        return None, "the model does not drive it"
    try:
        target = derive_target(scenario, reading.other, opposite, index, other_id=reading.agent)  # type: ignore[arg-type]
    except TargetUnavailable as exc:
        return None, f"no target: {exc.detail}"
    return target, ""
