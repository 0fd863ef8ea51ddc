"""Judges by numbers of the safety-critical pair behaviours: whether the manoeuvre a prompt asks was completed on the
played scene with the numbers asked (a cut-in's gap, a braking lead's deceleration, ...) within a stated tolerance,
before any contact between the two agents; each returns the realised values beside the asked ones
(docs/testing.md, 'Judged by numbers').

One module per behaviour (`cut_in`, `overtake_cut_in`, `brake_hard`, `tailgate`, `pull_out`, `run_red_light`), each
a `judge(scene, agent, other, asked) -> Judgement` (track ids; `asked`: the behaviour's parameters by name,
checked by `BehaviourKind.judge`), which the behaviour's module declares as its judge (`BehaviourKind.judged`);
`base` holds the records and the shared geometry.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

from langtraj.interdrive.judging.base import Judgement, Measure
from langtraj.scenario.model import Scenario

Judge = Callable[[Scenario, int, int, Mapping[str, float]], Judgement]
"""A judge: (played scene, agent's track id, other's track id, asked numbers) -> its judgement."""

__all__ = ["Judge", "Judgement", "Measure"]
