"""Steering recipes several behaviours share: standing at a stop point, a stop after a manoeuvre, being at a station
when the target says, and keeping a gap ahead of the other agent. Each gives `Steer` records (`base.Steer`) in
simulated steps. Common range (as the guidance library's): a clear violation (1 m off the route, 5 m short of a goal,
2 m/s of speed error) costs about 1. See docs/simulation.md ('Prompts that steer')."""

from __future__ import annotations

import numpy as np

from langtraj.interdrive.behaviours.base import (
    HOLD_WEIGHT,
    REACH_WEIGHT,
    Steer,
    lead,
    speed,
    station,
    steps,
)
from langtraj.interdrive.targets.target import BehaviourTarget
from langtraj.scenario.model import FUTURE_STEPS

LEAD_SLACK_M = 2.0
"""How far beyond its settled lead an agent cutting in may get ahead of the other before it has settled (m)."""


def settled(target: BehaviourTarget) -> int:
    """The simulated step by which the target times its goal (`settled_s`), which a timed kind's target must give."""
    if target.settled_s is None:
        raise ValueError(f"a {target.behaviour!s} target must say when it is settled (settled_s)")
    return steps(target.settled_s)


def stand(target: BehaviourTarget, standing: int) -> list[Steer]:
    """Never past the stop point; standing still from simulated step `standing` on."""
    goal = target.station_of_goal or 0.0
    return station(goal, "hold", 1, FUTURE_STEPS, HOLD_WEIGHT) + speed(0.0, standing)


def stop_step(target: BehaviourTarget) -> int:
    """When braking evenly from the current speed to the goal station brings the agent to rest (at most 6 s)."""
    goal, v = target.station_of_goal or 0.0, max(target.current_speed, 0.1)
    return int(np.clip(steps(2 * goal / v), 10, 60))


def then_stop(target: BehaviourTarget) -> list[Steer]:
    """A stop after a manoeuvre (`interdrive.targets.stop_after`, which times it): standing still at its stop from
    when the target has it stand (`settled_s`: driving on, then braking comfortably)."""
    if target.settled_s is None:
        raise ValueError(f"a stop after {target.behaviour!s} needs its time to stand (settled_s)")
    return stand(target, int(np.clip(steps(target.settled_s), 10, FUTURE_STEPS - 10)))


def at_station_then_speed(target: BehaviourTarget) -> list[Steer]:
    """At the goal station when the target says (`settled_s`), not past it before; at the other agent's speed
    after."""
    when = settled(target)
    other_speed = target.other_speed if target.other_speed is not None else target.current_speed
    goal = float(target.station_of_goal or 0.0)
    return (
        station(goal, "reach", when, when + 5, REACH_WEIGHT)
        + station(goal, "hold", 1, when, HOLD_WEIGHT)
        + speed(other_speed, when)
    )


def gap_ahead(target: BehaviourTarget, other_driven: bool) -> list[Steer]:
    """The gap ahead of the other agent from when the target says it has settled, and never more than
    `LEAD_SLACK_M` beyond it before, measured against where the other agent drives in the plan (`lead`), so that an
    agent cut in on that slows down is still cut in on. Where the model does not drive the other agent: at the goal
    station when settled, not past it before, at the other's speed after (`at_station_then_speed`)."""
    if not other_driven or target.lead_m is None:
        return at_station_then_speed(target)
    when = settled(target)
    return lead(target.lead_m, "reach", when, FUTURE_STEPS, REACH_WEIGHT) + lead(
        target.lead_m + LEAD_SLACK_M, "hold", 1, FUTURE_STEPS, HOLD_WEIGHT
    )
