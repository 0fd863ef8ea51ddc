"""The one verdict on a prompt's reading in a played scene: followed when the labelers find the behaviour
(`PromptReading.followed`) and, for a behaviour judged by numbers, its judge says the manoeuvre was completed as
asked (`BehaviourKind.judge`), with the realised numbers beside the asked ones and one line saying why not. The
suites (`suites.happened`) and the studio judge by it (docs/testing.md, 'Judged by numbers')."""

from __future__ import annotations

from dataclasses import dataclass, replace

from langtraj.errors import InputError
from langtraj.interdrive.adherence import Fact
from langtraj.interdrive.behaviours.base import kind
from langtraj.interdrive.judging import Judgement, Measure
from langtraj.interdrive.reader.read import PromptReading
from langtraj.interdrive.triggers import AtTime
from langtraj.scenario.model import Scenario


@dataclass(frozen=True)
class Verdict:
    """`followed`: True, False, or None where it cannot be judged; `why` not followed or not judged (None when
    followed); `measures`: asked and realised numbers (empty for a behaviour judged by the labelers alone)."""

    followed: bool | None
    why: str | None = None
    measures: tuple[Measure, ...] = ()


@dataclass(frozen=True)
class Start:
    """When a staged behaviour started in a played rollout (`sim.staging`): the step and seconds since the start, or
    None with why it never did (its trigger never held, or the scene gave no target when it did)."""

    step: int | None
    seconds: float | None = None
    why: str = ""


def judge_reading(
    reading: PromptReading, played: Scenario, found: frozenset[Fact], start: Start | None = None
) -> Verdict:
    """The verdict on `reading` in `played` (the history and the simulated steps), the labelers having `found` the
    facts `found` there (`AdherenceChecker.facts`). A staged reading (`start` given: `sim.staging`) is judged by its
    numbers from its start on, the manoeuvre after its trigger, with when it started among the measures; one that
    never started is not followed, with why."""
    why = reading.unjudged({int(i) for i in played.agents.ids})
    if why is not None:
        return Verdict(None, why)
    if start is not None:
        if start.step is None:
            return Verdict(False, f"it never started: {start.why}")
        started = Measure("started", "s", _asked_start(reading), start.seconds, None, None)
        verdict = judge_reading(replace(reading, trigger=None), replace(played, current_index=start.step), found)
        return replace(verdict, measures=(started, *verdict.measures))
    labelers = reading.followed(found)
    assert reading.behaviour is not None and reading.agent is not None
    try:
        asked = reading.asked()
    except InputError as exc:  # an ask the prompt check refuses before a run: not judged
        return Verdict(None, exc.detail)
    judgement = kind(reading.behaviour).judge(played, reading.agent, reading.other, asked)
    if judgement is None:
        return Verdict(labelers)
    followed, why = by_numbers(labelers, judgement)
    return Verdict(followed, why, tuple(judgement.measures))


def by_numbers(labelers: bool | None, judgement: Judgement) -> tuple[bool | None, str | None]:
    """The verdict and its reason when the labelers say `labelers` and the numbers `judgement`: followed only when
    both say so."""
    if labelers is None:
        return None, None
    if labelers and judgement.happened:
        return True, None
    if labelers:
        return False, judgement.why
    if judgement.happened:
        return False, f"the labelers did not see it, though by its numbers: {judgement.why}"
    return False, f"{judgement.why}; the labelers did not see it either"


def _asked_start(reading: PromptReading) -> float | None:
    """The start a reading's trigger asks in seconds, where it says one ("after 3 s"); None for a condition."""
    return reading.trigger.seconds if isinstance(reading.trigger, AtTime) else None
