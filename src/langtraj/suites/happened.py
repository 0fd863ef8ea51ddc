"""Whether an episode's scenario happened: each prompt of the case, read as the simulation read it
(`sim.prompts.read_prompts`), judged on the played episode by the one verdict of the suites and the studio
(`interdrive.behaviours.verdict`: the labelers' facts, `PromptReading.followed`, and for the safety-critical pair
behaviours their numbers too, `BehaviourKind.judge`: a cut-in's gap, a braking lead's deceleration, ... as asked,
within tolerance, before any contact). An episode whose planner kept every criterion while a prompt was not
followed did not test what the case asks: its status is `not_happened`, not a pass (docs/testing.md, 'Scenario
suites' and 'Judged by numbers')."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from langtraj.interdrive.adherence import AdherenceChecker
from langtraj.interdrive.behaviours.verdict import Start, judge_reading
from langtraj.interdrive.judging import Measure
from langtraj.scenario.model import Scenario
from langtraj.sim.prompts import read_prompts


@dataclass(frozen=True)
class PromptVerdict:
    """One clause of a prompt of an episode: the prompt's `text`, how the clause was read (`reading`:
    `PromptReading.describe()`; `behaviour`, `agent`, `other`), and `followed`: True or False as the labelers judge
    the played episode and, for a behaviour judged by numbers, as its judge does too (both must say it happened),
    None where it cannot be judged. `why`: why it was not judged (nothing was read, or an agent it names is not in
    the scene) or not followed (the numbers' one line, e.g. `gap 2.5 m done, 15 m asked (+-3 m)`); None when
    followed. `measures`: the asked and realised numbers of a behaviour judged by numbers (empty for the rest)."""

    text: str
    reading: str
    behaviour: str | None
    agent: int | None
    other: int | None
    followed: bool | None
    why: str | None = None
    measures: list[Measure] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        return {
            "text": self.text,
            "reading": self.reading,
            "behaviour": self.behaviour,
            "agent": self.agent,
            "other": self.other,
            "followed": self.followed,
            "why": self.why,
            "measures": [m.to_json() for m in self.measures],
        }


def judge_prompts(
    played: Scenario, texts: Sequence[str], starts: Mapping[int, Start] | None = None
) -> list[PromptVerdict]:
    """Each clause of `texts` (the prompts as the env ran them, `@ego` replaced) judged on `played` (the history and
    the simulated steps: `LangTrajEnv.played()`) by the one verdict (`behaviours.verdict.judge_reading`), a staged
    clause from when it started (`starts`, by agent: `sim.staging.starts_of`); the labelers run once, and only when
    some clause can be judged."""
    starts = starts or {}
    read = [(text, reading) for text in texts for reading in read_prompts([text], strict=False)]
    present = {int(i) for i in played.agents.ids}
    found = frozenset()
    if any(reading.unjudged(present) is None for _, reading in read):
        found = AdherenceChecker.build(played, logged=False).facts(played)
    out = []
    for text, reading in read:
        start = starts.get(reading.agent) if reading.agent is not None else None
        verdict = judge_reading(reading, played, found, start)
        out.append(
            PromptVerdict(
                text=text,
                reading=reading.describe(),
                behaviour=None if reading.behaviour is None else reading.behaviour.value,
                agent=reading.agent,
                other=reading.other,
                followed=verdict.followed,
                why=verdict.why,
                measures=list(verdict.measures),
            )
        )
    return out


def not_happened(verdicts: Sequence[PromptVerdict], warnings: Sequence[str] = ()) -> list[str]:
    """One reason per prompt the played episode did not follow, with why where known (empty: the scenario happened,
    as far as judged). A prompt the scene ruled out before the run (one of the simulation's `warnings` about its
    agent: "@12 cannot ...") says so first, so that it reads apart from a model that failed."""
    out = []
    for v in verdicts:
        if v.followed is not False:
            continue
        ruled_out = next((w for w in warnings if v.agent is not None and w.startswith(f"@{v.agent} ")), None)
        head = (
            f"scenario could not happen: {v.text!r} ({v.reading}): the scene ruled it out before the run ({ruled_out})"
            if ruled_out
            else f"scenario did not happen: {v.text!r} ({v.reading}) not followed"
        )
        out.append(head + (f": {v.why}" if v.why else ""))
    return out
