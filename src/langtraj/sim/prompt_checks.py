"""The one check of typed prompts, before anything runs: for each prompt, whether it can be run (and why not, in one
line), how the reader reads it clause by clause, whether the map gives its behaviours a target (and the warning
`langtraj simulate` prints when it does not: a behaviour the map rules out is warned about, not refused, and a suite
reports it as "scenario did not happen"), and the targets; plus the adversary and target. `simulate` (`sim.setup`),
the env (with its ego: a prompt asking something of the ego is refused), suites and the studio all ask this function,
so they accept and refuse the same prompts with the same message (docs/simulation.md, 'From words to rollouts';
docs/studio.md, 'POST /api/scenes/{key}/prompts')."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from langtraj.errors import InputError
from langtraj.interdrive.prompts import MAX_PROMPT_CHARS  # the prompt parser's limit, checked before reading
from langtraj.interdrive.reader import PromptReading
from langtraj.interdrive.targets import BehaviourTarget
from langtraj.roads import MapIndex
from langtraj.rollouts.agents import sim_agent_indices
from langtraj.scenario.model import Scenario
from langtraj.sim.config import ALL_LEVERS
from langtraj.sim.prompts import prompt_steering, read_prompts, user_prompt_entry
from langtraj.sim.terms import pair_problem

_WORLD: tuple[float, float, float] = (0.0, 0.0, 0.0)
"""The frame the steering terms are built in; the checks use only the world-frame targets."""


@dataclass(frozen=True)
class PromptCheck:
    """One prompt: `error` says why it cannot be run (None: it can); `readings` what the reader made of each clause
    (empty when it was refused before reading); `feasible` whether the map gives every read behaviour a target (None:
    not read, or targets not asked for); `warning` the lines `langtraj simulate` warns with (a behaviour the map
    rules out: the run goes on and a suite reports the scenario as not happened); `targets` where they steer."""

    text: str
    error: str | None = None
    readings: tuple[PromptReading, ...] = ()
    feasible: bool | None = None
    warning: str | None = None
    targets: tuple[BehaviourTarget, ...] = ()

    @property
    def ok(self) -> bool:
        return self.error is None

    def to_json(self) -> dict[str, Any]:
        """`reading` is the first clause read (every clause's line in its `describe`), `readings` each clause's."""
        reading = None
        if self.readings:
            first = next((r for r in self.readings if r.read), self.readings[0])
            reading = first.to_json() | {"describe": "; ".join(r.describe() for r in self.readings)}
        return {
            "text": self.text,
            "ok": self.ok,
            "error": self.error,
            "reading": reading,
            "readings": [r.to_json() | {"describe": r.describe()} for r in self.readings],
            "feasible": self.feasible,
            "warning": self.warning,
            "target": target_json(self.targets[0]) if self.targets else None,
            "targets": [target_json(t) for t in self.targets],
        }


@dataclass(frozen=True)
class PromptChecks:
    """Every prompt's check and the adversary/target problem (`error`)."""

    prompts: tuple[PromptCheck, ...]
    error: str | None = None

    @property
    def ok(self) -> bool:
        return self.error is None and all(p.ok for p in self.prompts)

    def first_error(self) -> str | None:
        """One line for a refused job: the first problem found, naming its prompt."""
        if self.error is not None:
            return self.error
        for i, check in enumerate(self.prompts):
            if check.error is not None:
                return f"prompts[{i}]: {check.error}"
        return None

    def to_json(self) -> dict[str, Any]:
        return {"ok": self.ok, "prompts": [p.to_json() for p in self.prompts], "error": self.error}


def target_json(target: BehaviourTarget) -> dict[str, Any]:
    """The page's form of a target: its agent and behaviour, the path (every 2 m), the stop point where the agent
    must stand still, the conflict point of a pair behaviour and the other agent (world frame, metres to the
    centimetre)."""
    full = target.to_json()
    return {
        "agent": target.track_id,
        "behaviour": target.behaviour.value,
        "path": full["path"] or None,
        "stop": full["goal"] if target.stop else None,
        "conflict": full["conflict"],
        "other": target.other_id,
    }


def check_prompts(
    scenario: Scenario,
    texts: Sequence[str],
    adversary: int | None = None,
    target: int | None = None,
    index: MapIndex | None = None,
    *,
    ego: int | None = None,
    targets: bool = True,
) -> PromptChecks:
    """Check `texts` against `scenario` (`index`: its map index, built here when not given). `ego`: the track a
    planner drives, which no prompt may ask something of and which cannot be the adversary. `targets`: whether to
    derive each behaviour's target (False where the caller steers by them anyway and needs the refusals alone)."""
    rows = sim_agent_indices(scenario)
    sim_ids = [int(i) for i in scenario.agents.ids[rows]]
    if targets and index is None:
        index = MapIndex.build(scenario.road_map)
    named: dict[int, int] = {}
    checks = []
    for number, text in enumerate(texts):
        check = _check(scenario, text, number, sim_ids, rows, named, index if targets else None, ego)
        checks.append(check)
    return PromptChecks(tuple(checks), _pair_error(adversary, target, sim_ids, ego))


def _check(
    scenario: Scenario,
    text: str,
    number: int,
    sim_ids: list[int],
    rows: np.ndarray,
    named: dict[int, int],
    index: MapIndex | None,
    ego: int | None,
) -> PromptCheck:
    if len(text) > MAX_PROMPT_CHARS:  # never passed on: a paste gone wrong must not reach the reader
        return PromptCheck(text, f"prompt is {len(text)} characters long; the limit is {MAX_PROMPT_CHARS}")
    try:
        entry = user_prompt_entry(scenario, text)
    except InputError as exc:
        return PromptCheck(text, str(exc))
    outside = [m for m in entry.mentions if m not in sim_ids]
    if outside:
        which = ", ".join(f"@{m}" for m in outside)
        return PromptCheck(text, f"{which} not valid at the current step: the simulation moves only the sim agents")
    again = [m for m in entry.mentions if m in named]
    if again:
        m = again[0]
        return PromptCheck(text, f"@{m} is named by prompt {named[m] + 1} too; describe each agent in one prompt")
    if ego is not None and _asks_ego(read_prompts([text], strict=False), entry.mentions, ego):
        return PromptCheck(text, f"{text!r} asks something of the ego, which the planner drives")
    for m in entry.mentions:
        named[m] = number
    try:
        readings = read_prompts([text])
    except InputError as exc:
        return PromptCheck(text, str(exc))
    if not any(r.read for r in readings) or index is None:
        return PromptCheck(text, None, readings)
    steering = prompt_steering(scenario, readings, rows, _WORLD, ALL_LEVERS, index)
    own = tuple(t for t in steering.targets if t.track_id in {r.agent for r in readings})
    warning = "; ".join(steering.warnings) or None
    feasible = {t.track_id for t in own} >= {r.agent for r in readings if r.read}
    return PromptCheck(text, None, readings, feasible, warning, own)


def _asks_ego(readings: Sequence[PromptReading], mentions: Sequence[int], ego: int) -> bool:
    """Whether a prompt asks something of the ego: a clause read as asking it, or, where no clause is read, the
    first agent it names; not where it names the ego in timing words ("when @ego is 20 m behind, @7 brakes hard"),
    which the strict reading refuses for what they are."""
    asked = [r.agent for r in readings if r.read]
    if asked:
        return ego in asked
    return not any(r.condition for r in readings) and bool(mentions) and mentions[0] == ego


def _pair_error(adversary: int | None, target: int | None, sim_ids: list[int], ego: int | None) -> str | None:
    """What is wrong with a collision pair (`sim.terms.pair_problem`, as `langtraj simulate` refuses it), or None."""
    problem = pair_problem(adversary, target, sim_ids=set(sim_ids), ego=ego)
    return None if problem is None else problem[1]
