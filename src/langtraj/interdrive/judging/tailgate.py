"""Tailgating judged by its numbers: the agent follows the other in the other's driven path, at 5 m/s or more, under
0.6 s of headway (bumper to bumper over its speed) for at least a second, at a median headway of 0.4 s within
tolerance, before any contact between the two (docs/testing.md, 'Judged by numbers').

A prompt asks no number of a tailgater: the simulation steers it to `TARGET_HEADWAY_S`, and the interaction detector
calls under `TAILGATING_HEADWAY_S` at `TAILGATING_SPEED` or more tailgating. Reported: the median headway over the
first second-long stretch under 0.6 s (else over every step it follows), the shortest headway, and the longest time
under 0.6 s.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from langtraj.interdrive.judging.base import (
    Judgement,
    Measure,
    at,
    cut_short,
    how_other_drove,
    not_seen,
    pair_view,
)
from langtraj.runs import true_runs
from langtraj.scenario.model import STEP_SECONDS, Scenario

TARGET_HEADWAY_S = 0.4
"""The headway a tailgater is asked for (s): the one the simulation steers it to."""
HEADWAY_TOLERANCE_S = 0.2
"""The tolerance of the median headway either side (s): up to the detector's 0.6 s, and no nearer than 0.2 s (2 m at
10 m/s: riding the bumper, no longer a tailgater's gap)."""
TAILGATING_HEADWAY_S = 0.6
"""Under this headway (s), at `TAILGATING_SPEED` or more, a follower tailgates (the detector's
`tailgating_headway_s`)."""
TAILGATING_SPEED = 5.0
"""The least speed (m/s) of a tailgater (the detector's `tailgating_speed`): slower, a short gap is a queue."""
TAILGATING_HOLD_S = 1.0
"""How long (s) the headway must stay under `TAILGATING_HEADWAY_S` (the detector's one-second following runs)."""


def _measures(median: float | None, under: float, shortest: float | None) -> tuple[Measure, ...]:
    ok = median is not None and abs(median - TARGET_HEADWAY_S) <= HEADWAY_TOLERANCE_S
    return (
        Measure("headway", "s", TARGET_HEADWAY_S, median, HEADWAY_TOLERANCE_S, ok),
        Measure(f"time under {TAILGATING_HEADWAY_S:g} s", "s", None, under, None, under >= TAILGATING_HOLD_S),
        Measure("shortest headway", "s", None, shortest, None, None),
    )


def judge(scene: Scenario, agent: int, other: int, asked: Mapping[str, float]) -> Judgement:
    """Whether track `agent` tailgated track `other` in the played `scene` (`asked` must be empty): under 0.6 s of
    headway for a second at a median of 0.4 s within `HEADWAY_TOLERANCE_S`, before any contact between the two."""
    view = pair_view(scene, agent, other)
    name, contact = f"@{other}", view.contact_step
    speed = view.agent.speed
    with np.errstate(invalid="ignore"):
        following = view.in_path() & (view.gap_behind > 0.0) & (speed >= TAILGATING_SPEED) & view.before_contact()
        headway = np.where(following, view.gap_behind / np.where(following, speed, 1.0), np.nan)
        under = following & (headway < TAILGATING_HEADWAY_S)
    hold = round(TAILGATING_HOLD_S / STEP_SECONDS)
    runs = true_runs(under)
    first = next(((s, e) for s, e in runs if e - s >= hold), None)
    chosen = first or max(runs, key=lambda r: r[1] - r[0], default=None)
    if chosen is not None:
        median: float | None = float(np.median(headway[chosen[0] : chosen[1]]))
    else:
        median = float(np.median(headway[following])) if following.any() else None
    longest = max((e - s for s, e in runs), default=0) * STEP_SECONDS
    shortest = float(np.min(headway[following])) if following.any() else None
    measures = _measures(median, longest, shortest)
    done = None if first is None else first[0] + hold
    why = not_seen(view)
    if why is None and first is None:
        if contact is not None:
            why = cut_short(contact)
        elif not following.any():
            why = f"never behind {name} in its path at {TAILGATING_SPEED:g} m/s or more"
        else:
            why = (
                f"under {TAILGATING_HEADWAY_S:g} s of headway for {at(round(longest / STEP_SECONDS))}, not the "
                f"{TAILGATING_HOLD_S:g} s tailgating needs ({measures[0].missed()})"
            )
    if why is None and not measures[0].ok:
        why = measures[0].missed()
    if why is not None:
        drove = None if contact is not None else how_other_drove(view)
        return Judgement(False, measures, why if drove is None else f"{why}; {drove}", done, contact)
    return Judgement(
        True, measures, f"tailgated {name} at a median {median:.2f} s of headway from {at(first[0])}", done, contact
    )
