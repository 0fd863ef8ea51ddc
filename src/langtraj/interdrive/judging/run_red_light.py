"""A red light run across another agent's path, judged by its numbers: the agent's front passes a signal's stop line
while that signal shows red (the played scene's lights at that step), then, within `CROSSING_WITHIN_S`, its centre
crosses the other's driven path ahead of the other, the other's front at most `REACH_S` at its speed (or `REACH_M`)
from the crossing, before any contact between the two (docs/testing.md, 'Judged by numbers').

A stop line is a signal's stop point within `STOP_LINE_LATERAL_M` of the agent's heading line (the interaction
detector's rule); reported: when it crossed the line, how long the light had shown red by then (since the start), the
other's distance to the crossing and the time that gives at the other's speed when the light was run.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from langtraj.interdrive.judging.base import (
    EPSILON_SPEED,
    STOOD_MPS,
    Judgement,
    Measure,
    PairView,
    Track,
    at,
    cut_short,
    not_seen,
    pair_view,
)
from langtraj.scenario.model import STEP_SECONDS, Scenario
from langtraj.scenario.types import RED_STATES, TrafficLightState

STOP_LINE_LATERAL_M = 2.0
"""A stop point this close (m) to the agent's heading line is on its way (the detector's `red_lateral`; lanes are
about 3.5 m apart)."""
CROSSING_WITHIN_S = 4.0
"""The agent crosses the other's path at most this long (s) after running the light (the detector's
`red_crossing_s`)."""
OFF_PATH_M = 2.5
"""When it runs the light the agent's centre is more than this (m) off the other's path: nearer, it drives ahead of
the other in its lane, it does not cross its path (the detector's `red_conflict_radius`)."""
ON_PATH_M = 1.0
"""The agent crosses the other's path where its centre changes side of it or comes this close (m)."""
SIDE_CHANGE_M = 3.0
"""A change of side counts only between two steps both this close (m) to the path, so that the nearest part of a
curved path changing does not read as a crossing."""
REACH_S = 4.0
"""The other's front is at most this long (s, at its speed when the light was run) from the crossing: farther, the
run cut no one's way (the detector's `foe_horizon_s`)."""
REACH_M = 15.0
"""... or at most this far (m), for a slow or standing other (the detector's `red_foe_range`)."""


def stop_line_crossings(scene: Scenario, runner: Track) -> list[tuple[int, int]]:
    """(step, signal state) of each step at which `runner`'s front passes a signal's stop point on its way, counted
    from the current step (the state UNKNOWN where the light is not valid then)."""
    lights = scene.traffic_lights
    n = len(runner.valid)
    if lights is None or lights.num_lanes == 0 or n < 2:
        return []
    first = min(int(scene.current_index), scene.num_steps - 1)
    states = np.zeros((n, lights.num_lanes), np.int64)
    valid = np.zeros((n, lights.num_lanes), bool)
    have = max(0, min(n, len(lights.states) - first))
    states[:have], valid[:have] = lights.states[first : first + have], lights.valid[first : first + have]
    rel = lights.stop_points[None, :, :2] - runner.xy[:, None, :]  # [n, L, 2]
    cos, sin = np.cos(runner.heading)[:, None], np.sin(runner.heading)[:, None]
    ahead = rel[..., 0] * cos + rel[..., 1] * sin - 0.5 * runner.length[:, None]
    lateral = np.abs(rel[..., 1] * cos - rel[..., 0] * sin)
    with np.errstate(invalid="ignore"):
        passed = (ahead[:-1] > 0.0) & (ahead[1:] <= 0.0) & (lateral[1:] < STOP_LINE_LATERAL_M)
    passed &= (runner.valid[:-1] & runner.valid[1:])[:, None]
    out = []
    for step, lane in zip(*np.nonzero(passed), strict=True):
        state = int(states[step + 1, lane]) if valid[step + 1, lane] else int(TrafficLightState.UNKNOWN)
        out.append((int(step) + 1, state))
    return out


def _red_for(scene: Scenario, runner: Track, step: int) -> float:
    """How long (s) the signal whose stop line the runner passed at `step` had shown red by then, since the current
    step at most (the stop point nearest its front; 0 when it turned red at that step)."""
    lights = scene.traffic_lights
    first = min(int(scene.current_index), scene.num_steps - 1)
    heading = runner.heading[step]
    front = runner.xy[step] + 0.5 * runner.length[step] * np.array([np.cos(heading), np.sin(heading)])
    lane = int(np.argmin(np.linalg.norm(lights.stop_points[:, :2] - front, axis=1)))
    red = np.isin(lights.states[first : first + step + 1, lane], [int(s) for s in RED_STATES])
    red &= lights.valid[first : first + step + 1, lane]
    count = 0
    for value in red[::-1]:
        if not value:
            break
        count += 1
    return max(count - 1, 0) * STEP_SECONDS


def path_crossing(view: PairView, start: int) -> int | None:
    """The first step after `start`, within `CROSSING_WITHIN_S` and before any contact, at which the agent's centre
    crosses the other's path (changes side of it, or comes within `ON_PATH_M`); None when it does not."""
    end = min(view.steps, start + round(CROSSING_WITHIN_S / STEP_SECONDS) + 1)
    if view.contact_step is not None:
        end = min(end, view.contact_step)
    across, both = view.across, view.both
    for t in range(start + 1, end):
        if not (both[t] and both[t - 1]):
            continue
        near = abs(across[t]) < SIDE_CHANGE_M and abs(across[t - 1]) < SIDE_CHANGE_M
        if abs(across[t]) < ON_PATH_M or (near and np.sign(across[t]) != np.sign(across[t - 1])):
            return t
    return None


def _stood_for(view: PairView) -> str:
    """Where a runner that never crossed a stop line stood to the end: since when, and how the other drove meanwhile
    (its mean speed and how near it came), so that a run the other's driving ruled out says so; '' where it did not
    stand."""
    moving = np.flatnonzero(~(view.agent.speed < STOOD_MPS) & view.agent.valid)
    since = 0 if not moving.size else int(moving[-1]) + 1
    steps = np.arange(since, len(view.both))[view.both[since:]]
    if since >= len(view.both) - 1 or not steps.size:
        return ""
    gap = np.hypot(*(view.other.xy[steps] - view.agent.xy[steps]).T)
    speed = float(np.nanmean(view.other.speed[steps]))
    return (
        f": it stood short of it from {at(since)} (waiting for @{view.other.track_id}); @{view.other.track_id} "
        f"drove at {speed:.1f} m/s meanwhile and came no nearer than {float(gap.min()):.0f} m"
    )


def _measures(
    crossed: float | None, red_for: float | None, distance: float | None, ahead: float | None, reach: float | None
) -> tuple[Measure, ...]:
    ok = None if distance is None or reach is None else 0.0 < distance <= reach
    return (
        Measure("crossing on red", "s", None, crossed, None, crossed is not None),
        Measure("red for", "s", None, red_for, None, None),
        Measure("other's front to the crossing", "m", None, distance, None, ok),
        Measure("time ahead of the other", "s", None, ahead, None, None),
    )


def judge(scene: Scenario, agent: int, other: int, asked: Mapping[str, float]) -> Judgement:
    """Whether track `agent` ran a red light across track `other`'s path in the played `scene` (`asked` must be
    empty): over a red stop line, then across the other's path before the other, before any contact between the
    two."""
    view = pair_view(scene, agent, other)
    name, contact = f"@{other}", view.contact_step
    crossings = stop_line_crossings(scene, view.agent)
    red = next((step for step, state in crossings if state in RED_STATES), None)
    why = not_seen(view)
    if why is None and red is None:
        if crossings:
            step, state = crossings[0]
            why = f"crossed a stop line at {at(step)} on {TrafficLightState(state).name.lower()}, not red"
        else:
            why = "never crossed a signal's stop line" + _stood_for(view)
    if why is not None or red is None:
        return Judgement(False, _measures(None, None, None, None, None), why or "", None, contact)
    red_for = _red_for(scene, view.agent, red)
    if contact is not None and contact <= red:
        return Judgement(
            False, _measures(red * STEP_SECONDS, red_for, None, None, None), cut_short(contact), None, contact
        )
    if not view.both[red] or abs(view.across[red]) <= OFF_PATH_M:
        why = f"in {name}'s path when it ran the light: it drove ahead of {name}, it did not cross its path"
        return Judgement(False, _measures(red * STEP_SECONDS, red_for, None, None, None), why, None, contact)
    cross = path_crossing(view, red)
    if cross is None:
        why = (
            cut_short(contact) if contact is not None else f"never crossed {name}'s path within {CROSSING_WITHIN_S:g} s"
        )
        return Judgement(False, _measures(red * STEP_SECONDS, red_for, None, None, None), why, None, contact)
    speed = float(view.other.speed[red]) if np.isfinite(view.other.speed[red]) else 0.0
    distance = float(view.along[cross] - 0.5 * view.other.length[cross])
    reach = max(REACH_S * speed, REACH_M)
    ahead = distance / speed if speed >= EPSILON_SPEED else None
    measures = _measures(red * STEP_SECONDS, red_for, distance, ahead, reach)
    if distance <= 0.0:
        why = f"crossed {name}'s path {-distance:.1f} m behind its front: {name} was there first"
    elif distance > reach:
        why = f"{name} was {distance:.0f} m from the crossing when it crossed: no one's way cut"
    else:
        timing = "" if ahead is None else f", {ahead:.1f} s ahead of it"
        why = f"ran the red light at {at(red)} and crossed {name}'s path {distance:.1f} m before it{timing}"
        return Judgement(True, measures, why, cross, contact)
    return Judgement(False, measures, why, cross, contact)
