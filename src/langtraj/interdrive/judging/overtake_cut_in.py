"""An overtake and cut-in judged by its numbers: the agent, behind or beside the other at first, passes it on its
own side (the side it was on when first out of the other's path, never crossing the other's path to the far side),
then settles in the other's path ahead of it (as a cut-in settles, `cut_in.settling`) with the gap asked, within
tolerance, before any contact between the two (docs/testing.md, 'Judged by numbers').

Reported beside the gap: the passing speed (the agent's when its centre draws level with the other's) and how much
faster than the other it was then, and how far it went over to the far side of the other's path before settling.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from langtraj.interdrive.judging.base import (
    Judgement,
    Measure,
    asked_value,
    not_seen,
    pair_view,
)
from langtraj.interdrive.judging.cut_in import (
    SETTLED_LATERAL_M,
    gap_tolerance,
    judge_settling,
    out_of_path_step,
    settling,
)
from langtraj.scenario.model import Scenario

FAR_SIDE_M = SETTLED_LATERAL_M
"""How far (m) the agent's centre may go past the other's path to its far side before it settles: as far as a settled
car may be off that path either way. Further, it crossed the other's lane: it did not pass on its own side."""


def _measures(far: float | None, speeds: tuple[float, float] | None) -> tuple[Measure, ...]:
    passing = None if speeds is None else speeds[0]
    faster = None if speeds is None else speeds[0] - speeds[1]
    return (
        Measure("passing speed", "m/s", None, passing, None, None),
        Measure("faster than the other", "m/s", None, faster, None, None),
        Measure("over to the far side", "m", 0.0, far, FAR_SIDE_M, None if far is None else far <= FAR_SIDE_M),
    )


def judge(scene: Scenario, agent: int, other: int, asked: Mapping[str, float]) -> Judgement:
    """Whether track `agent` overtook track `other` on its own side and cut in front of it in the played `scene` with
    the gap `asked` ("gap", m; the behaviour's default when the prompt gives none), within `gap_tolerance`, before
    any contact."""
    asked_gap = asked_value(asked, "gap")
    view = pair_view(scene, agent, other)
    name = f"@{other}"
    with np.errstate(invalid="ignore"):
        behind = np.flatnonzero(view.both & (view.along < view.half_lengths))  # its rear behind the other's front
    out = out_of_path_step(view)
    why = not_seen(view)
    if why is None and not behind.size:
        why = f"never behind or beside {name}: a cut-in, not an overtake"
    if why is None and out is None:
        why = f"never out of {name}'s path: it followed, it did not overtake"
    if why is not None or out is None:
        measures = (*_measures(None, None), Measure("gap", "m", asked_gap, None, gap_tolerance(asked_gap), False))
        return Judgement(False, measures, why or "", None, view.contact_step)
    first = int(behind[0])
    after = max(out, first)
    side = 1.0 if view.across[out] > 0 else -1.0
    end = view.steps
    step = settling(view, after)
    for stop in (step, view.contact_step):
        if stop is not None:
            end = min(end, stop)
    far = float(np.nanmax(np.maximum(-side * view.across[:end], 0.0), initial=0.0))
    with np.errstate(invalid="ignore"):
        level = np.flatnonzero(view.both[first:end] & (view.along[first:end] >= 0.0))
    speeds = None
    if level.size:
        k = first + int(level[0])
        speeds = (float(view.agent.speed[k]), float(view.other.speed[k]))
    return judge_settling(scene, view, asked_gap, after, _measures(far, speeds))
