"""A cut-in judged by its numbers: the agent, out of the other's path at first, settles in it ahead of the other, and
the gap it leaves (bumper to bumper, along the other's driven path) when it enters the other's lane on its way to
settling is the gap asked, within tolerance, before any contact between the two (docs/testing.md, 'Judged by
numbers').

Settled: the agent's centre within `SETTLED_LATERAL_M` of the other's path, its heading within `SETTLED_HEADING`
of the path's, ahead of the other, held `SETTLED_HOLD_S` (or until the other runs into it). The overtake and cut-in
(`overtake_cut_in`) settles by the same rule.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from langtraj.interdrive.judging.base import (
    FELL_BACK_MPS,
    Judgement,
    Measure,
    PairView,
    around,
    asked_value,
    at,
    cut_short,
    how_other_drove,
    not_seen,
    pair_view,
)
from langtraj.runs import true_runs
from langtraj.scenario.model import STEP_SECONDS, Scenario

"""What a prompt may ask of a cut-in: `gap`, bumper to bumper in metres ("with a 15 m gap")."""
GAP_TOLERANCE_M = 3.0
"""The least tolerance of the gap either side (m): the gap is read at the step the agent settles, when the two still
differ in speed by 1 to 3 m/s, and where within a second it settles moves the gap by as much."""
GAP_TOLERANCE_SHARE = 0.2
"""Beyond 15 m the tolerance is this share of the asked gap: a 30-m gap is met at 24 to 36 m."""
SETTLED_LATERAL_M = 1.0
"""A settled agent's centre is at most this far (m) from the other's path: in a 3.5-m lane a 2-m-wide car this far
off the other's line is wholly in the other's lane; half in it is 1.75 m or more."""
SETTLED_HEADING = math.radians(8.0)
"""A settled agent heads along the other's path within this (rad): a lane change turns 3 to 8 degrees, so a car
still turned further is still changing lanes."""
SETTLED_HOLD_S = 1.0
"""How long the agent must stay settled (s), unless the other runs into it first: a car that crosses the other's path
and goes on out of it does not cut in."""
ENTERED_LATERAL_M = 1.75
"""A cut-in has entered the other's lane when its centre is this near (m) the other's path (half a 3.5-m lane): the gap
it leaves is read then, when it cuts in (as Euro NCAP reads a cut-in at the lane crossing), not when it has
settled, by which time the follower may have braked for it."""
OUT_OF_PATH_M = 2.0
"""Before settling, the agent's centre was this far (m) or more from the other's path at some step: a car already in
the other's path leads it, it does not cut in (lanes are about 3.5 m apart)."""


def gap_tolerance(asked_gap: float) -> float:
    """The tolerance (m) of an asked gap either side: `GAP_TOLERANCE_M`, or `GAP_TOLERANCE_SHARE` of the gap."""
    return max(GAP_TOLERANCE_M, GAP_TOLERANCE_SHARE * asked_gap)


def settled(view: PairView) -> np.ndarray:
    """bool [n]: the agent is settled in the other's path ahead of it at each step (without the hold)."""
    with np.errstate(invalid="ignore"):
        return (
            view.both
            & (np.abs(view.across) <= SETTLED_LATERAL_M)
            & (np.abs(view.heading_off) <= SETTLED_HEADING)
            & (view.gap_ahead > 0.0)
        )


def out_of_path_step(view: PairView) -> int | None:
    """The first step at which the agent's centre was `OUT_OF_PATH_M` or more from the other's path, or None."""
    with np.errstate(invalid="ignore"):
        out = np.flatnonzero(view.both & (np.abs(view.across) >= OUT_OF_PATH_M))
    return int(out[0]) if out.size else None


def settling(view: PairView, after: int) -> int | None:
    """The first step at or after `after` from which the agent stays settled for `SETTLED_HOLD_S`, or until a contact
    between the two (the other ran into it), before that contact; None when there is none."""
    hold = round(SETTLED_HOLD_S / STEP_SECONDS)
    contact = view.contact_step
    for start, end in true_runs(settled(view)):
        if start < after or (contact is not None and start >= contact):
            continue
        if end - start >= hold or (contact is not None and start < contact <= end):
            return start
    return None


def entered(view: PairView, after: int, settled_at: int) -> int:
    """The step at which the agent, settled from `settled_at`, entered the other's lane (`ENTERED_LATERAL_M`) ahead
    of it: the first of the steps up to `settled_at` it has since stayed in the lane, not before `after`."""
    with np.errstate(invalid="ignore"):
        outside = ~(view.both & (np.abs(view.across) <= ENTERED_LATERAL_M) & (view.gap_ahead > 0.0))
    before = np.flatnonzero(outside[after : settled_at + 1])
    return after + int(before[-1]) + 1 if before.size else after


def slowed(view: PairView, step: int) -> str | None:
    """One line saying the other had slowed by `step` (`FELL_BACK_MPS` or more below its first known speed), else
    None: a gap wider than asked that a follower braking early opened, not the cut-in."""
    speed = view.other.speed
    known = np.flatnonzero(np.isfinite(speed[: step + 1]))
    if known.size < 2:
        return None
    first, now = float(speed[known[0]]), float(speed[known[-1]])
    if now > first - FELL_BACK_MPS:
        return None
    return f"@{view.other.track_id} had slowed from {first:.1f} to {now:.1f} m/s by then (its own doing)"


def never_settled(view: PairView, after: int, asked_gap: float) -> str:
    """Why the agent never settled in the other's path ahead of it after step `after` (one line): where it stayed
    beside the other, out of its path, how far ahead of the other's front it was meanwhile against `asked_gap` (a
    cut-in waits beside until it is near its gap: an other that never came up to it, or left it behind, says so)."""
    other = f"@{view.other.track_id}"
    steps = np.arange(view.steps) >= after
    with np.errstate(invalid="ignore"):
        ahead = steps & view.both & (view.gap_ahead > 0.0)
    if not ahead.any():
        return f"never ahead of {other} in its path"
    runs = [end - start for start, end in true_runs(settled(view) & steps)]
    if runs:
        return (
            f"in {other}'s path ahead of it for at most {at(max(runs))}, not the {SETTLED_HOLD_S:g} s that settles it"
        )
    closest = float(np.nanmin(np.abs(view.across[ahead])))
    if closest <= SETTLED_LATERAL_M:
        return f"never settled in {other}'s path: still turned across it when in it"
    why = f"never settled in {other}'s path ahead of it (at closest {closest:.1f} m to its side)"
    with np.errstate(invalid="ignore"):
        beside = steps & view.both & (np.abs(view.across) >= OUT_OF_PATH_M)
    if not beside.any():
        return why
    gaps = view.gap_ahead[beside]
    low, high = float(np.nanmin(gaps)), float(np.nanmax(gaps))
    asked = f"({asked_gap:g} m asked)"
    if low < 0.0:
        return f"{why}: beside it, from {-low:.0f} m behind {other}'s front to {high:.0f} m ahead {asked}"
    return f"{why}: beside it, {low:.0f}-{high:.0f} m ahead of {other}'s front {asked}"


HELD_AHEAD_M = 25.0
"""A third car this close (m, bumper to bumper) ahead of a cut-in that stays short of its gap beside the other, in
its own lane (`HELD_LATERAL_M`), held it back (`held_behind`)."""
HELD_LATERAL_M = 1.5
"""... its centre within this (m) of the cut-in's heading line."""
HELD_SHARE = 0.5
"""... at this share of those steps or more."""


def held_behind(scene: Scenario, view: PairView, after: int, asked_gap: float) -> str | None:
    """Who held the cut-in back, where it stayed beside the other short of `asked_gap` after step `after`: the agent
    most often ahead of it in its own lane within `HELD_AHEAD_M` (at `HELD_SHARE` of those steps or more), as "held
    behind @12 in its own lane (6-9 m ahead of it)"; None where none did. The traffic's doing, not the other's."""
    with np.errstate(invalid="ignore"):
        short = (np.arange(view.steps) >= after) & view.both & (np.abs(view.across) >= OUT_OF_PATH_M)
        short &= view.gap_ahead < asked_gap - gap_tolerance(asked_gap)
    steps = np.flatnonzero(short)
    if not steps.size:
        return None
    seen = around(scene, view.agent, steps, (view.agent.track_id, view.other.track_id))
    ahead = seen.ahead - seen.half - 0.5 * view.agent.length[steps]
    held = seen.counts & (ahead > 0.0) & (ahead <= HELD_AHEAD_M) & (seen.off <= HELD_LATERAL_M)
    counts = held.sum(axis=1)
    best = int(np.argmax(counts))
    if counts[best] < HELD_SHARE * len(steps):
        return None
    gaps = ahead[best][held[best]]
    return f"held behind @{int(seen.ids[best])} in its own lane ({gaps.min():.0f}-{gaps.max():.0f} m ahead of it)"


def judge_settling(
    scene: Scenario, view: PairView, asked_gap: float, after: int, extra: tuple[Measure, ...] = ()
) -> Judgement:
    """The cut-in's verdict on `scene` once the agent was out of the other's path at step `after`: its gap when it
    settles against `asked_gap`, and the time it took; `extra` measures (an overtake's) precede them, and any of them
    not ok fails it too. Where it never settled, who held it back in its own lane says so too (`held_behind`)."""
    other = f"@{view.other.track_id}"
    contact = view.contact_step
    step = settling(view, after)
    tolerance = gap_tolerance(asked_gap)
    gap = None if step is None else float(view.gap_ahead[entered(view, after, step)])
    ok = None if gap is None else abs(gap - asked_gap) <= tolerance
    measures = (
        *extra,
        Measure("gap", "m", asked_gap, gap, tolerance, bool(ok) if ok is not None else False),
        Measure("time to settle", "s", None, None if step is None else step * STEP_SECONDS, None, None),
    )
    missed = [m.missed() for m in measures if m.ok is False and m.realised is not None]
    if gap is not None and step is not None and gap > asked_gap + tolerance:
        missed += [fell_back] if (fell_back := slowed(view, entered(view, after, step))) else []
    if step is None:
        why = cut_short(contact) if contact is not None else never_settled(view, after, asked_gap)
        drove = None if contact is not None else how_other_drove(view)
        held = None if contact is not None else held_behind(scene, view, after, asked_gap)
        why = "; ".join([why, *([held] if held else []), *([drove] if drove else []), *missed])
        return Judgement(False, measures, why, None, contact)
    if missed:
        return Judgement(False, measures, "; ".join(missed), step, contact)
    why = f"settled {gap:.1f} m ahead of {other} in its path at {at(step)} ({measures[-2].describe()})"
    return Judgement(True, measures, why, step, contact)


def judge(scene: Scenario, agent: int, other: int, asked: Mapping[str, float]) -> Judgement:
    """Whether track `agent` cut in front of track `other` in the played `scene` with the gap `asked` ("gap", m;
    the behaviour's default when the prompt gives none), within `gap_tolerance`, before any contact between the two."""
    asked_gap = asked_value(asked, "gap")
    view = pair_view(scene, agent, other)
    unseen = not_seen(view)
    after = None if unseen else out_of_path_step(view)
    if unseen or after is None:
        why = unseen or f"@{agent} was in @{other}'s path from the start: it leads, it does not cut in"
        gap = Measure("gap", "m", asked_gap, None, gap_tolerance(asked_gap), False)
        return Judgement(
            False, (gap, Measure("time to settle", "s", None, None, None, None)), why, None, view.contact_step
        )
    return judge_settling(scene, view, asked_gap, after)
