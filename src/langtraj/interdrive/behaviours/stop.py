"""Stopping and standing still: a stop on the way ahead where comfortable braking brings the agent to rest (at a stop
line or before a crosswalk when one lies a little beyond), judged by the labelers' static label.
See docs/interdrive.md ('Targets and feasibility')."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from langtraj.interdrive.behaviour import Behaviour, BehaviourSpec
from langtraj.interdrive.behaviours.base import ROUTE_WEIGHT, BehaviourKind, Steer, register, route
from langtraj.interdrive.behaviours.recipes import stand, stop_step
from langtraj.interdrive.reader.words import POSSESSIVE, SLOT, verb
from langtraj.interdrive.targets.context import COMFORT_DECELERATION, AgentHere, TargetContext
from langtraj.interdrive.targets.target import BehaviourTarget
from langtraj.polylines import arc_lengths, project_on_polyline

# ---------------------------------------------------------------------------------------------- words

_STOP_NOUN = r"(?:stop|halt|standstill)"
_STOP = [
    rf"(?<!non-)(?<!bus\s)\b{verb('stop', 'halt')}\b(?!\s+(?:sign|line|lights?)\b|-)",
    rf"\b(?:{verb('come', 'draw', 'grind', 'roll', 'brake', 'slow', 'slow down', 'ease')}"
    rf"|{verb('bring')}\s+(?:it|(?P<agent>{SLOT})))\s+(?:in)?to\s+a"
    rf"(?:\s+(?:full|complete|dead|total|sudden|quick|gentle|smooth|controlled))?\s+{_STOP_NOUN}\b",
    r"\b(?:at\s+a\s+)?standstill\b",
    rf"\b(?:{verb('stand', 'stay', 'remain', 'keep', 'sit', 'hold')}|is|are|be|being|been)\s+"
    r"(?:completely\s+|perfectly\s+|totally\s+|absolutely\s+|dead\s+)?(?:still|stationary|motionless|static|put)\b"
    r"(?!\s+\w+ing\b)",
    rf"\b{verb('stay', 'remain')}\s+in\s+place\b|\b{verb('hold')}\s+{POSSESSIVE}\s+position\b",
    r"\b(?:stationary|motionless)\b",
    r"\b(?:(?:does|do|is|are)\s+not|doesn't|don't|isn't|aren't|not)\s+(?:move|moving)\b"
    r"(?!\s+(?:over|into|across|aside|out|left|right|to|onto|off|away|up)\b)",
    rf"\b{verb('freeze')}\b",
    rf"\b{verb('pull')}\s+up\b",
]

# ---------------------------------------------------------------------------------------------- target


def _stop(ctx: TargetContext, agent: AgentHere) -> BehaviourTarget:
    """A stop on the way ahead where comfortable braking brings the agent to rest; at a stop line (the start of the
    next junction or a signal's stop point) or before a crosswalk when one lies a little beyond that, but no farther
    than the agent gets braking evenly over 7 s."""
    index = ctx.index
    path = ctx.ahead(agent)
    v = agent.here.speed
    comfort = v * v / (2 * COMFORT_DECELERATION) + 0.5 * agent.length
    latest = max(comfort, 0.5 * v * 7.0)
    reason, station = f"where braking at {COMFORT_DECELERATION:g} m/s^2 brings it to rest", comfort
    marks: list[tuple[float, str]] = []
    if agent.on_lane and index.has_connectivity and not index.is_junction[agent.here.lane]:
        marks.append((index.distance_to_junction(agent.here.lane, agent.here.station) - 1.0, "at the stop line"))
    lights = ctx.scenario.traffic_lights
    if lights is not None and len(lights.stop_points):
        found = project_on_polyline(np.asarray(lights.stop_points)[:, :2], path)
        marks += [
            (float(s) - 1.0, "at the signal's stop line")
            for s, d in zip(found.station, found.distance, strict=True)
            if d < 2.5
        ]
    crossing = index.in_crosswalk(path) if index.has_crosswalks else np.zeros(len(path), bool)
    if crossing.any():
        marks.append((float(arc_lengths(path)[int(np.argmax(crossing))]) - 2.0, "before the crosswalk"))
    for s, why in sorted(marks):
        if comfort <= s + 0.5 * agent.length <= latest + 0.5 * agent.length:
            station, reason = s, why
            break
    return BehaviourTarget(
        agent.track_id,
        Behaviour.STOP,
        path,
        f"a stop {station:.0f} m ahead, {reason}",
        station_of_goal=float(station),
        speed=0.0,
        current_speed=v,
    )


@register
class Stop(BehaviourKind):
    """Coming to a stop and standing still."""

    name = "stop"
    spec = BehaviourSpec(Behaviour.STOP, "@{agent} comes to a stop and stands still", "stop", "static")
    words = tuple(_STOP)
    word_rank = 7
    subsumes = ("slow_down",)

    def target(
        self, ctx: TargetContext, agent: AgentHere, other: AgentHere | None, asked: Mapping[str, float]
    ) -> BehaviourTarget:
        return _stop(ctx, agent)

    def steer(self, target: BehaviourTarget, other_driven: bool) -> list[Steer]:
        """Never past the stop point; standing still from when even braking gets there."""
        return stand(target, stop_step(target)) + route(weight=0.25 * ROUTE_WEIGHT)
