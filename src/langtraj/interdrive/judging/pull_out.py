"""Pulling out in front of another agent, judged by its numbers: the agent, waiting off the other's driven path (at
`WAIT_SPEED` or less, `OFF_WAY_M` or more to its side), sets off and comes onto that path ahead of the other within
`LOOKBACK_S`, with a margin (its bumper gap ahead of the other over the other's speed when it set off) of
`TARGET_MARGIN_S` within tolerance, before any contact between the two (docs/testing.md, 'Judged by numbers').

The other's speed is read when the agent sets off, not when it arrives: an other that brakes for the car pulling out,
as it should, leaves the pull-out as it was.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from langtraj.interdrive.judging.base import (
    EPSILON_SPEED,
    Judgement,
    Measure,
    PairView,
    at,
    cut_short,
    how_other_drove,
    not_seen,
    pair_view,
)
from langtraj.runs import true_runs
from langtraj.scenario.model import STEP_SECONDS, Scenario

TARGET_MARGIN_S = 2.0
"""The margin a pull-out is judged against (s): the simulation sets the agent off to be on the other's way this long
before the other gets there (the two-second rule, broken for the other)."""
MARGIN_TOLERANCE_S = 1.0
"""The tolerance of the margin either side (s): under 1 s the other cannot brake in time (a crash, not a pull-out);
over 3 s it had time to see the car come out and the road ahead of it is free again."""
WAIT_SPEED = 3.0
"""The most the agent moves (m/s) while waiting to pull out: standing or creeping (the detector's `pull_out_speed`)."""
OFF_WAY_M = 2.5
"""While waiting, the agent's centre is more than this (m) off the other's path: in a side road, a driveway or at the
kerb, not in the other's lane (the detector's `red_conflict_radius`)."""
ON_WAY_M = 1.5
"""The agent is on the other's way where its centre comes this close (m) to the other's path, ahead of the other
(the detector's `pull_out_on_line`)."""
OTHER_MIN_SPEED = 3.0
"""The least speed (m/s) of the other when the agent sets off: slower, no one is pulled out in front of."""
LOOKBACK_S = 4.0
"""The agent set off at most this long (s) before coming onto the other's way: earlier, it was driving, not pulling
out (the detector's `pull_out_lookback_s`)."""


def _measures(margin: float | None, speed: float | None, gap: float | None) -> tuple[Measure, ...]:
    ok = margin is not None and abs(margin - TARGET_MARGIN_S) <= MARGIN_TOLERANCE_S
    return (
        Measure("margin", "s", TARGET_MARGIN_S, margin, MARGIN_TOLERANCE_S, ok),
        Measure("other's speed when it set off", "m/s", None, speed, None, None),
        Measure("gap ahead on its way", "m", None, gap, None, None),
    )


def judge(scene: Scenario, agent: int, other: int, asked: Mapping[str, float]) -> Judgement:
    """Whether track `agent` pulled out in front of track `other` in the played `scene` (`asked` must be empty) with a
    margin of `TARGET_MARGIN_S` within `MARGIN_TOLERANCE_S`, before any contact between the two."""
    view = pair_view(scene, agent, other)
    name, contact = f"@{other}", view.contact_step
    with np.errstate(invalid="ignore"):
        near = view.both & (np.abs(view.across) <= ON_WAY_M)
        waiting = view.both & (np.abs(view.across) > OFF_WAY_M) & (view.agent.speed <= WAIT_SPEED)
        on_way = near & (view.gap_ahead > 0.0) & view.before_contact()
    lookback = round(LOOKBACK_S / STEP_SECONDS)
    entry = set_off = None
    for start, _ in true_runs(on_way):
        before = np.flatnonzero(waiting[max(start - lookback, 0) : start])
        if start > 0 and before.size:
            entry, set_off = start, max(start - lookback, 0) + int(before[-1])
            break
    why = not_seen(view)
    if why is None and not waiting.any():
        why = f"never waited off {name}'s way ({WAIT_SPEED:g} m/s or less, over {OFF_WAY_M:g} m to its side)"
    if entry is None or set_off is None:
        if why is None:
            went = np.flatnonzero(waiting)[0]
            if contact is not None:
                why = cut_short(contact)
            elif not near[went:].any():
                why = f"never came onto {name}'s way"
            elif not on_way[went:].any():
                why = f"came onto {name}'s way only behind it"
            else:
                why = f"set off more than {LOOKBACK_S:g} s before coming onto {name}'s way"
            why = _with_how_other_drove(why, view, contact)
        return Judgement(False, _measures(None, None, None), why, None, contact)
    speed = float(view.other.speed[set_off])
    gap = float(view.gap_ahead[entry])
    measures = _measures(gap / max(speed, EPSILON_SPEED), speed, gap)
    if speed < OTHER_MIN_SPEED:
        why = f"{name} was all but standing ({speed:.1f} m/s) when it set off: no one to pull out in front of"
        return Judgement(False, measures, why, entry, contact)
    if not measures[0].ok:
        return Judgement(False, measures, _with_how_other_drove(measures[0].missed(), view, contact), entry, contact)
    why = f"pulled out {gap:.1f} m ahead of {name} at {at(entry)} ({measures[0].describe()})"
    return Judgement(True, measures, why, entry, contact)


def _with_how_other_drove(why: str, view: PairView, contact: int | None) -> str:
    """`why` and, before any contact, how the other changed its speed meanwhile (`how_other_drove`): a margin wider
    than asked, or a pull-out never on the other's way, beside an ego that slowed or sped up reads as its doing."""
    drove = None if contact is not None else how_other_drove(view)
    return why if drove is None else f"{why}; {drove}"
