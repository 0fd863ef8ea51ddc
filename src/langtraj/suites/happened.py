"""Whether an episode's scenario happened: each prompt of the case, read as the simulation read it
(`sim.prompts.read_prompts`), judged on the played episode by the labelers (`AdherenceChecker.facts`,
`PromptReading.followed`), the one judge of the studio and of instruction following. An episode whose planner kept
every criterion while a prompt was not followed did not test what the case asks: its status is `not_happened`,
not a pass (docs/testing.md, 'Scenario suites')."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from langtraj.interdrive.adherence import AdherenceChecker
from langtraj.scenario.model import Scenario
from langtraj.sim.prompts import read_prompts


@dataclass(frozen=True)
class PromptVerdict:
    """One clause of a prompt of an episode: the prompt's `text`, how the clause was read (`reading`:
    `PromptReading.describe()`; `behaviour`, `agent`, `other`), and `followed`: True or False as the labelers judge
    the played episode, None where it cannot be judged (`why`: nothing was read, or an agent it names is not in the
    scene)."""

    text: str
    reading: str
    behaviour: str | None
    agent: int | None
    other: int | None
    followed: bool | None
    why: str | None = None

    def to_json(self) -> dict[str, Any]:
        return {
            "text": self.text,
            "reading": self.reading,
            "behaviour": self.behaviour,
            "agent": self.agent,
            "other": self.other,
            "followed": self.followed,
            "why": self.why,
        }


def judge_prompts(played: Scenario, texts: Sequence[str]) -> list[PromptVerdict]:
    """Each clause of `texts` (the prompts as the env ran them, `@ego` replaced) judged on `played` (the history and
    the simulated steps: `LangTrajEnv.played()`); the labelers run once, and only when some clause can be judged."""
    read = [(text, reading) for text in texts for reading in read_prompts([text], strict=False)]
    present = {int(i) for i in played.agents.ids}
    why = [reading.unjudged(present) for _, reading in read]
    found = frozenset()
    if any(w is None for w in why):
        found = AdherenceChecker.build(played, logged=False).facts(played)
    out = []
    for (text, reading), reason in zip(read, why, strict=True):
        verdict = reading.followed(found) if reason is None else None
        out.append(
            PromptVerdict(
                text=text,
                reading=reading.describe(),
                behaviour=None if reading.behaviour is None else reading.behaviour.value,
                agent=reading.agent,
                other=reading.other,
                followed=verdict,
                why=reason,
            )
        )
    return out


def not_happened(verdicts: Sequence[PromptVerdict]) -> list[str]:
    """One reason per prompt the played episode did not follow (empty: the scenario happened, as far as judged)."""
    return [f"scenario did not happen: {v.text!r} ({v.reading}) not followed" for v in verdicts if v.followed is False]
