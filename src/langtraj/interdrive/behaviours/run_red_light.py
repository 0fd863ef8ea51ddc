"""Running a red light across another agent's way (NHTSA's running-a-red-light pre-crash scenario): through a signal
showing stop and across the other's way before it; judged by the detector's red-light rule and by its numbers.
See docs/interdrive.md ('Targets and feasibility')."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from langtraj.interdrive.behaviour import Behaviour, BehaviourSpec
from langtraj.interdrive.behaviours.base import ROUTE_WEIGHT, BehaviourKind, Steer, register, speed, steps
from langtraj.interdrive.behaviours.go_first import go_first_terms
from langtraj.interdrive.behaviours.scripts import Crossing, Script
from langtraj.interdrive.detector import red_light_runs
from langtraj.interdrive.judging import run_red_light as judged_by
from langtraj.interdrive.reader.words import OTHER, TIGHT_GAP, verb
from langtraj.interdrive.targets.context import (
    NOT_GO_STATES,
    RED_STOP_LATERAL,
    AgentHere,
    TargetContext,
    check_going_first,
    crossing,
    red_before,
    stop_points,
)
from langtraj.interdrive.targets.target import BehaviourTarget, TargetUnavailable
from langtraj.interdrive.taxonomy import InteractionType
from langtraj.polylines import arc_lengths, project_on_polyline
from langtraj.scenario.model import FUTURE_STEPS
from langtraj.scenario.types import RED_STATES

RED_LIGHT_SPEED = 8.0
"""The least speed a red-light runner crosses at (m/s): a car that jumps the light does not creep."""
RED_LIGHT_REACH_S = 4.0
"""How far ahead, in time at that speed, the red light may be (s): later, it may well have turned green."""
RED_LIGHT_ROUTE_WEIGHT = 1.25 * ROUTE_WEIGHT
"""Per m^2 off its way, for a red-light runner: going first's quarter weight and the usual one on top, as measured
(docs/testing.md, 'Red lights run by name, measured')."""

# ---------------------------------------------------------------------------------------------- words

_RED = r"(?:a\s+|the\s+|its\s+|their\s+)?(?:red\s+(?:light|signal|traffic\s+light)s?|red|stop\s+light|light\s+on\s+red)"
_WHOSE_PATH = rf"(?:the\s+(?:path|way|lane)\s+of\s+)?{OTHER}(?:'s\s+(?:path|way|lane))?"
_ACROSS = rf"(?:across|into|through|in\s+front\s+of|ahead\s+of|right\s+in\s+front\s+of|before)\s+{_WHOSE_PATH}"
_RED_VERBS = verb(
    "run", "jump", "skip", "ignore", "blow through", "blow", "go through", "drive through", "speed through",
    "race through", "shoot through", "cross on", "go on", "drive on", "run through", "disregard",
)  # fmt: skip
_RUN_RED_LIGHT = [
    rf"\b{_RED_VERBS}\s+{_RED}(?!\w)",
    rf"\b{_RED_VERBS}\s+{_RED}{TIGHT_GAP}\s+{_ACROSS}",
    rf"\b{verb('cross', 'enter', 'go through', 'drive through', 'pass through', 'cut across', 'drive across')}"
    rf"\s+(?:the\s+)?(?:junction|intersection|crossing)\s+(?:on|against|through)\s+(?:a\s+|the\s+)?red"
    rf"(?:\s+light)?{TIGHT_GAP}\s+{_ACROSS}",
    rf"\b{verb('cross', 'cut across', 'pull across', 'drive across')}\s+{_WHOSE_PATH}\s+(?:on|against|through)"
    r"\s+(?:a\s+|the\s+)?red(?:\s+light)?\b",
]
"""Running a red light across the other's path (NHTSA's running-a-red-light pre-crash scenario): "runs the red light
across @7's path", "jumps the red in front of @7", "crosses the junction on red in front of @7", "cuts across @7's
path on a red light"; or "runs the red light" alone, the other agent the one other mention ("ignores the red light
and goes in front of @7")."""

# ---------------------------------------------------------------------------------------------- target


def _run_red_light(ctx: TargetContext, agent: AgentHere, other: AgentHere) -> BehaviourTarget:
    """Through a signal showing stop at the current step and across the other's way: the first of the agent's ways
    ahead (`TargetContext.ways_ahead`) that passes within `RED_STOP_LATERAL` of the stop point of such a signal, no
    farther than `RED_LIGHT_REACH_S` at `RED_LIGHT_SPEED` (or its own speed, if faster), and that a way of the other
    agent crosses past it, the other facing no red or amber light before the crossing (it has the right of way); the
    goal is that crossing, passed first, at that speed, as going first (`_order`). Undecided without signals;
    infeasible without such a light and crossing, or where the other gets to the crossing first
    (`check_going_first`)."""
    behaviour = Behaviour.RUN_RED_LIGHT
    stops = stop_points(ctx, RED_STATES)
    if stops is None:
        raise TargetUnavailable(agent.track_id, behaviour, "undecided", "the scene has no traffic lights")
    if not len(stops):
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", "no signal shows red at the current step")
    speed = max(agent.here.speed, RED_LIGHT_SPEED)
    reach = speed * RED_LIGHT_REACH_S
    theirs = ctx.ways_ahead(other)
    reason = f"no red light on its way within {reach:.0f} m"
    for path in ctx.ways_ahead(agent):
        found = project_on_polyline(stops, path)
        on_way = (found.distance < RED_STOP_LATERAL) & (found.station > 0.0) & (found.station <= reach)
        if not on_way.any():
            continue
        light = float(found.station[on_way].min())
        if (queued := ctx.standing_on(agent, path, light)) is not None:
            reason = f"@{queued} stands between it and the red light {light:.0f} m ahead"
            continue
        arc = arc_lengths(path)
        crossings = [c for c in (crossing(path, t) for t in theirs) if c is not None and arc[c[0]] > light]
        if not crossings:
            reason = f"@{other.track_id}'s way does not cross its way past the red light {light:.0f} m ahead"
            continue
        i, distance = min(crossings)
        if red_before(stop_points(ctx, NOT_GO_STATES), theirs, path[i]):
            reason = f"@{other.track_id} faces a red or amber light too, before the crossing: no right of way to cut"
            continue
        target = BehaviourTarget(
            agent.track_id,
            behaviour,
            path,
            f"through the red light {light:.0f} m ahead at {speed:.1f} m/s, across @{other.track_id}'s way "
            f"{arc[i]:.0f} m ahead, before it",
            station_of_goal=float(arc[i]),
            speed=float(speed),
            other_id=other.track_id,
            conflict=path[i],
            other_eta=distance / max(other.here.speed, 1.0),
            current_speed=agent.here.speed,
            other_speed=other.here.speed,
            stop_line_m=light,
        )
        check_going_first(agent, other, target)
        return target
    raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)


@register
class RunRedLight(BehaviourKind):
    """Running a red light across another agent's way."""

    name = "run_red_light"
    spec = BehaviourSpec(
        Behaviour.RUN_RED_LIGHT, "@{agent} runs the red light across the path of @{other}",
        "run the red light across the path of", interaction=InteractionType.PASSING,
        subtype="passing/red_light_running", exact=True, conditioned_as=Behaviour.GO_FIRST, first=True,
    )  # fmt: skip
    words = tuple(_RUN_RED_LIGHT)
    word_rank = 15
    subsumes = ("go_first", "speed_up", "go_straight")
    in_path = True
    judged = staticmethod(judged_by.judge)
    pair_runs = staticmethod(red_light_runs)

    def target(
        self, ctx: TargetContext, agent: AgentHere, other: AgentHere | None, asked: Mapping[str, float]
    ) -> BehaviourTarget:
        assert other is not None
        return _run_red_light(ctx, agent, other)

    def script(self, target: BehaviourTarget) -> Script | None:
        """Through the red light along its way into the other's way as it drives, timed so that the other, keeping its
        speed, would run into its side, standing short of the stop line while early (`Crossing`): guidance alone left
        the runner, which learned to stop at red lights, short of the stop line in 7 of 24 held-out episodes, and a
        runner past the crossing 2 s ahead of the other cut no one's way (docs/testing.md, 'Red lights run into the
        ego's way')."""
        if target.station_of_goal is None:
            return None
        return Crossing(float(target.station_of_goal), float(target.speed or 0.0), target.stop_line_m)

    def steer(self, target: BehaviourTarget, other_driven: bool) -> list[Steer]:
        """As going first (past the crossing a second before the other agent gets there, clear of it), through the
        red light at its target speed from 1 s until then, on its way throughout: the model, which learned to stop
        at red lights, is held to it."""
        by = int(np.clip(steps((target.other_eta or 0.0) - 1.0), 10, FUTURE_STEPS))
        return go_first_terms(target, RED_LIGHT_ROUTE_WEIGHT) + speed(float(target.speed or 0.0), steps(1.0), by)
