"""A lead braking hard in front of its follower, judged by its numbers: the lead, ahead of the follower in the
follower's driven path, brakes with the peak deceleration asked (over 0.5 s, within tolerance) and stays in that path
while it brakes; a lead that swerves out of the path did not brake in front of anyone (docs/testing.md, 'Judged by
numbers').

The braking is the run of 0.5-s windows slowing the lead by more than `BRAKING_FLOOR` around its hardest one; the
asked braking is done at the end of the first window reaching the asked deceleration less its tolerance. Windows are
read before any contact between the two (a contact first cuts the braking short).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from langtraj.interdrive.judging.base import (
    IN_PATH_HEADING,
    IN_PATH_LATERAL_M,
    Judgement,
    Measure,
    PairView,
    around,
    asked_value,
    at,
    cut_short,
    decelerations,
    not_seen,
    pair_view,
)
from langtraj.runs import true_runs
from langtraj.scenario.model import STEP_SECONDS, Scenario

"""What a prompt may ask of a braking lead: `deceleration` in m/s^2 ("at 6 m/s^2", "at 0.5 g")."""
DECELERATION_TOLERANCE = 1.5
"""The least tolerance of the peak deceleration either side (m/s^2): positions at 10 Hz read over 0.5 s give the
deceleration to a few tenths, and a driver's (or the model's) hard stop swings by about 1 m/s^2 about its mean."""
DECELERATION_TOLERANCE_SHARE = 0.25
"""Beyond 6 m/s^2 the tolerance is this share of the asked deceleration (8 is met at 6 to 10)."""
PEAK_WINDOW_S = 0.5
"""The span a deceleration is averaged over (s): the interaction detector's hard braking (`hard_braking_steps`)."""
BRAKING_FLOOR = 2.0
"""Slowing by more than this (m/s^2, over 0.5 s) is braking, not easing off: the span checked for staying in the
path runs over the windows above it around the hardest one."""
MIN_SPEED = 3.0
"""The least speed (m/s) a lead brakes from: slower, a stop is too short to judge (the detector's
`hard_braking_speed`)."""
FOLLOWER_RANGE_M = 60.0
"""The follower's front at most this far (m) behind the lead's rear when the braking begins: farther, no one is
braked in front of (the detector's `leader_range`)."""


def deceleration_tolerance(asked: float) -> float:
    """The tolerance (m/s^2) of an asked deceleration either side."""
    return max(DECELERATION_TOLERANCE, DECELERATION_TOLERANCE_SHARE * asked)


def _usable(view: PairView, steps: int) -> np.ndarray:
    """bool [n]: the windows [t, t + steps] both agents are valid at both ends of, the lead at `MIN_SPEED` or more
    at their start, ending before any contact."""
    n = view.steps
    both = view.both
    end = np.zeros(n, bool)
    end[: max(n - steps, 0)] = both[steps:]
    with np.errstate(invalid="ignore"):
        out = both & end & (view.agent.speed >= MIN_SPEED)
    limit = n if view.contact_step is None else view.contact_step
    out[max(limit - steps, 0) :] = False
    return out


def came_between(scene: Scenario, view: PairView, span: np.ndarray) -> str | None:
    """The first agent but the two in the follower's path between them at a step of `span` (the braking): its centre
    within `IN_PATH_LATERAL_M` of the follower's heading line, ahead of the follower's front and behind the lead's
    rear, as "@92 came between @80 and it at 1.9 s"; None where none did. A car that moved in between was braked in
    front of, not the follower (the traffic's doing, which the labelers' nearest-leader rule sees too)."""
    if not span.size:
        return None
    follower = view.other
    seen = around(scene, follower, span, (view.agent.track_id, follower.track_id))
    with np.errstate(invalid="ignore"):
        between = (seen.ahead - seen.half > 0.5 * follower.length[span]) & (
            seen.ahead + seen.half < view.along[span] - 0.5 * view.agent.length[span]
        )
    between &= seen.counts & (seen.off <= IN_PATH_LATERAL_M)
    if not between.any():
        return None
    found = np.argwhere(between)  # [K, 2]: agent row, step of span
    who, step = found[np.argmin(found[:, 1])]
    return f"@{int(seen.ids[who])} came between @{follower.track_id} and it at {at(int(span[step]))}"


def judge(scene: Scenario, agent: int, other: int, asked: Mapping[str, float]) -> Judgement:
    """Whether track `agent` braked hard in front of track `other` in the played `scene` at the deceleration `asked`
    ("deceleration", m/s^2; the behaviour's default when the prompt gives none), within `deceleration_tolerance`,
    staying in the other's path while braking, before any contact between the two."""
    wanted = asked_value(asked, "deceleration")
    tolerance = deceleration_tolerance(wanted)
    view = pair_view(scene, agent, other)
    name, contact = f"@{other}", view.contact_step
    k = round(PEAK_WINDOW_S / STEP_SECONDS)
    dec = decelerations(view.agent.speed, k)
    usable = _usable(view, k) & np.isfinite(dec)
    hardest = float(np.max(dec[usable])) if usable.any() else None
    if not_seen(view) or hardest is None or hardest <= BRAKING_FLOOR:
        peak = Measure("peak deceleration", "m/s^2", wanted, hardest, tolerance, False)
        why = not_seen(view)
        if why is None:
            most = "" if hardest is None else f": at most {hardest:.1f} m/s^2 over {PEAK_WINDOW_S:g} s"
            why = cut_short(contact) if contact is not None else f"never braked hard at {MIN_SPEED:g} m/s or more{most}"
        return Judgement(False, (peak,), why, None, contact)
    peak_step = int(np.flatnonzero(usable & (dec == hardest))[0])
    braking = usable & (dec > BRAKING_FLOOR)
    start, stop = next((s, e) for s, e in true_runs(braking) if s <= peak_step < e)
    limit = view.steps if contact is None else contact
    span = np.arange(start, min(stop - 1 + k, limit - 1) + 1)
    span = span[view.both[span]]
    reached = np.flatnonzero(braking & (dec >= wanted - tolerance))
    reached = reached[(reached >= start) & (reached < stop)]
    done = int(reached[0]) + k if reached.size else None
    lateral = float(np.max(np.abs(view.across[span])))
    turned = math.degrees(float(np.max(np.abs(view.heading_off[span]))))
    gap = float(view.gap_ahead[start])
    measures = (
        Measure("peak deceleration", "m/s^2", wanted, hardest, tolerance, abs(hardest - wanted) <= tolerance),
        Measure("off the path", "m", 0.0, lateral, IN_PATH_LATERAL_M, lateral <= IN_PATH_LATERAL_M),
        Measure(
            "turned off the path",
            "deg",
            0.0,
            turned,
            math.degrees(IN_PATH_HEADING),
            turned <= math.degrees(IN_PATH_HEADING),
        ),
        Measure("speed when braking began", "m/s", None, float(view.agent.speed[start]), None, None),
        Measure("gap ahead when braking began", "m", None, gap, None, None),
    )
    reasons = []
    if gap <= 0.0:
        reasons.append(f"not ahead of {name} when it began braking at {at(start)}")
    elif gap > FOLLOWER_RANGE_M:
        reasons.append(f"{name} was {gap:.0f} m behind when it began braking: more than {FOLLOWER_RANGE_M:g} m")
    if (between := came_between(scene, view, span)) is not None:
        reasons.append(between)
    if not (measures[1].ok and measures[2].ok):
        reasons.append(
            f"did not brake in front of {name}: it left its path while braking ({lateral:.1f} m to the side, "
            f"turned {turned:.0f} deg)"
        )
    if done is None and contact is not None and hardest < wanted - tolerance:
        reasons.append(cut_short(contact))
    elif not measures[0].ok:
        reasons.append(measures[0].missed())
    if reasons:
        return Judgement(False, measures, "; ".join(reasons), done, contact)
    why = f"braked at {hardest:.1f} m/s^2 in front of {name} from {at(start)} ({measures[0].describe()})"
    return Judgement(True, measures, why, done, contact)
