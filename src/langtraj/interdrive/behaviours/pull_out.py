"""Pulling out in front of another agent from a side road, a driveway or the kerb (NHTSA's pre-crash scenarios at
non-signalized junctions): from (nearly) standing onto the other's way ahead of it, timed to be there a little
before it; judged by the detector's pull-out rule and by its numbers. See docs/interdrive.md ('Targets and
feasibility')."""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from langtraj.interdrive.behaviour import Behaviour, BehaviourSpec
from langtraj.interdrive.behaviours.base import (
    HOLD_WEIGHT,
    REACH_WEIGHT,
    BehaviourKind,
    Steer,
    lead,
    register,
    route,
    speed,
    station,
    steps,
)
from langtraj.interdrive.behaviours.recipes import settled
from langtraj.interdrive.detector import pull_out_runs
from langtraj.interdrive.judging import pull_out as judged_by
from langtraj.interdrive.reader.words import IN_FRONT, OTHER, TIGHT_GAP, verb
from langtraj.interdrive.targets.context import (
    HORIZON_S,
    JUDGE,
    AgentHere,
    TargetContext,
    red_on_way,
    time_to_cover,
)
from langtraj.interdrive.targets.target import BehaviourTarget, TargetUnavailable
from langtraj.interdrive.taxonomy import InteractionType
from langtraj.polylines import arc_lengths, point_at, project_on_polyline, resample
from langtraj.roads.routes import ROUTE_SPACING
from langtraj.scenario.model import FUTURE_STEPS
from langtraj.scenario.types import AgentType

PULL_OUT_MAX_SPEED = JUDGE.pull_out_speed
"""The most an agent asked to pull out may be moving (m/s; the judge's): a pull-out starts from standing or a
crawl."""
PULL_OUT_OTHER_MIN_SPEED = JUDGE.pull_out_other_speed
"""The least speed of the agent pulled out in front of (m/s; the judge's)."""
PULL_OUT_REACH_M = 30.0
"""How far along its way an agent pulling out may meet the other's way (m): farther, it is driving, not pulling out."""
PULL_OUT_MEET_M = 1.0
"""The agent's way meets the other's where it comes this close to it (m)."""
PULL_OUT_GAP_S = 2.0
"""How long before the other agent gets there the agent is where it pulls out onto the other's way (s), setting off
later where the other is farther: the two-second rule, broken for the other as the agent noses in."""
PULL_OUT_MIN_GAP_S = 1.0
"""The least such time (s): less, and the other cannot brake for it (a crash, not a pull-out)."""
PULL_OUT_LATEST_S = HORIZON_S - 2.0
"""The latest the other may get to where the agent pulls out (s): the judge sees the two after it."""
PULL_OUT_TOP_SPEED = 10.0
"""The speed an agent that has pulled out drives on at (m/s), or the other's, if slower."""
PULL_OUT_OFF_WAY_M = JUDGE.red_conflict_radius
"""How far from the other's way an agent pulling out must be (m; the judge's): nearer, it is on that way already (in
the lane, or standing in the junction across it)."""
PULL_OUT_REACH_WEIGHT = 16.0 * REACH_WEIGHT
"""Per m^2 short of the meeting point, for a pull-out: above the common range, as the model, trained where cars on a
side road wait for the main road, holds it at the mouth; chosen on validation maps (docs/testing.md, 'Pulling out by
name, measured')."""

# ---------------------------------------------------------------------------------------------- words

_PULL_OUT_VERBS = verb(
    "pull out", "nose out", "edge out", "creep out", "inch out", "emerge", "come out", "turn out", "shoot out",
    "dart out", "lurch out", "roll out", "back out", "reverse out", "pull away",
)  # fmt: skip
_PLACE = (
    r"(?:a|an|the|its|their|his|her)\s+(?:[\w-]+\s+)?(?:side\s+road|side\s+street|road|street|driveway|drive|junction"
    r"|intersection|parking\s+(?:spot|space|lot|bay)|car\s+park|kerb|curb|lane|alley|alleyway|entrance|exit|gate"
    r"|garage|forecourt|minor\s+road|t-junction)"
)
_FROM_PLACE = (
    rf"(?:\s+(?:of|from|out\s+of)\s+{_PLACE})?"
    r"(?:\s+(?:in)?to\s+(?:the\s+)?(?:road|street|traffic|lane|main\s+road))?"
)
_PULL_OUT = [
    rf"\b{_PULL_OUT_VERBS}(?:\s+(?:suddenly|right|just|sharply|abruptly|quickly|blindly|straight))*{_FROM_PLACE}"
    rf"\s+(?:{IN_FRONT}|(?:in)?to\s+the\s+(?:path|way)\s+of|across\s+the\s+path\s+of)\s+{OTHER}",
    rf"\b{_PULL_OUT_VERBS}(?:\s+(?:suddenly|right|just|sharply|abruptly|quickly|blindly|straight))*{_FROM_PLACE}"
    rf"\s+(?:in)?to\s+{OTHER}'s\s+(?:path|way|lane)\b",
    rf"\b{verb('pull', 'turn', 'come', 'drive', 'emerge')}\s+(?:(?:left|right)\s+)?(?:out\s+)?(?:of|from|out\s+of)"
    rf"\s+{_PLACE}"
    rf"{TIGHT_GAP}\s+{IN_FRONT}\s+{OTHER}",
]
"""Pulling out in front of the other from a side road, a driveway or the kerb (NHTSA's pre-crash scenarios at
non-signalized junctions): "pulls out in front of @7", "pulls out of the side road into the path of @7", "noses out
of a driveway into @7's lane", "emerges from the junction right in front of @7", "turns left out of the side road in
front of @7"."""

# ---------------------------------------------------------------------------------------------- target


def _pull_out(ctx: TargetContext, agent: AgentHere, other: AgentHere) -> BehaviourTarget:
    """From (nearly) standing onto the other's way ahead of it: the first of the agent's ways (`_pull_out_ways`)
    that comes within `PULL_OUT_MEET_M` of the other's way ahead of the other's front, within `PULL_OUT_REACH_M`
    (one that joins it, running on along it, before one that crosses it); the agent, speeding up as going first does,
    is there `PULL_OUT_GAP_S` before the other gets there at its speed, setting off later (`starts_s`) where the
    other is farther, and drives on at `PULL_OUT_TOP_SPEED` or the other's speed. Infeasible for an agent moving
    faster than `PULL_OUT_MAX_SPEED`, on the other's way already (within `PULL_OUT_OFF_WAY_M`), with no such meeting,
    or with a red light on its way before it (that is running the light); for an other slower than
    `PULL_OUT_OTHER_MIN_SPEED`, there later than `PULL_OUT_LATEST_S`, or too close to be there less than
    `PULL_OUT_MIN_GAP_S` after the agent."""
    behaviour, v, v_other = Behaviour.PULL_OUT, agent.here.speed, other.here.speed
    if agent.kind not in (AgentType.VEHICLE, AgentType.CYCLIST):
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", "only vehicles and cyclists pull out")
    if v > PULL_OUT_MAX_SPEED:
        reason = f"it is moving at {v:.1f} m/s: a pull-out starts from standing or a crawl "
        reason += f"(at most {PULL_OUT_MAX_SPEED:g})"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    if v_other < PULL_OUT_OTHER_MIN_SPEED:
        reason = f"@{other.track_id} is too slow to pull out in front of ({v_other:.1f} m/s; at least "
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason + f"{PULL_OUT_OTHER_MIN_SPEED:g})")
    theirs = ctx.ahead(other)
    if float(project_on_polyline(agent.xy, theirs).distance) <= PULL_OUT_OFF_WAY_M:
        reason = f"it is on @{other.track_id}'s way already: nothing to pull out of"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    clear = 0.5 * (agent.length + other.length) + 2.0  # its centre this far ahead of the other's, at least
    meetings = [m for m in (_meeting(path, theirs) for path in _pull_out_ways(ctx, agent, theirs)) if m is not None]
    meetings = [m for m in meetings if m[1] <= PULL_OUT_REACH_M and m[2] > clear]
    if not meetings:
        reason = f"none of its ways meets @{other.track_id}'s way ahead of it within {PULL_OUT_REACH_M:g} m"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    path, there, station, joins = min(meetings, key=lambda m: (not m[3], m[1]))
    if red_on_way(ctx, path, there):
        reason = f"its way shows red before @{other.track_id}'s: going on is running the red light"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    need = time_to_cover(there, v)
    other_there = (station - 0.5 * other.length) / max(v_other, 1e-6)
    if other_there > PULL_OUT_LATEST_S:
        reason = f"@{other.track_id} is {other_there:.1f} s from where it would pull out "
        reason += f"(at most {PULL_OUT_LATEST_S:g})"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    if other_there - need < PULL_OUT_MIN_GAP_S:
        reason = f"@{other.track_id} gets to where it would pull out in {other_there:.1f} s; it needs {need:.1f} s"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    starts = max(other_there - need - PULL_OUT_GAP_S, 0.0)
    how = "into" if joins else "across"
    return BehaviourTarget(
        agent.track_id,
        behaviour,
        path,
        f"out {how} @{other.track_id}'s way {there:.0f} m ahead from {starts:.1f} s, there by {starts + need:.1f} s, "
        f"{other_there - starts - need:.1f} s before it",
        station_of_goal=float(there),
        speed=float(min(PULL_OUT_TOP_SPEED, v_other)),
        other_id=other.track_id,
        conflict=point_at(path, there),
        other_eta=float(other_there),
        current_speed=v,
        other_speed=v_other,
        settled_s=float(starts + need),
        lead_m=float(clear) if joins else None,
        starts_s=float(starts),
    )


def _pull_out_ways(ctx: TargetContext, agent: AgentHere, theirs: np.ndarray) -> list[np.ndarray]:
    """The ways a pull-out may take: on a lane, its ways by the lane graph (`TargetContext.ways_ahead`); off lanes (a
    driveway, a car park, the kerb), a straight line onto the other's way `theirs`, meeting it as far past the point
    beside the agent as the agent is from it (at least 6 m), then along it, where the agent faces that point."""
    if ctx.index.has_lanes and agent.on_lane:
        return ctx.ways_ahead(agent)
    beside = project_on_polyline(agent.xy, theirs)
    station = float(beside.station) + max(6.0, float(beside.distance))
    entry = point_at(theirs, station)
    to_entry = entry - agent.xy
    facing = np.array([math.cos(agent.heading), math.sin(agent.heading)])
    if float(to_entry @ facing) <= 0.0:
        return []
    on = theirs[arc_lengths(theirs) > station]
    lead_in = resample(np.stack([agent.xy, entry]), ROUTE_SPACING)
    return [np.concatenate([lead_in[:-1], entry[None], on])]


def _meeting(path: np.ndarray, theirs: np.ndarray) -> tuple[np.ndarray, float, float, bool] | None:
    """Where `path` first comes within `PULL_OUT_MEET_M` of the other's way `theirs`: (path, the station along
    `path` there, the station along `theirs`, whether `path` joins it, running on within that of it 5 m later);
    None where it never does."""
    if len(path) < 2:
        return None
    found = project_on_polyline(path, theirs)
    near = np.flatnonzero(found.distance < PULL_OUT_MEET_M)
    if not near.size:
        return None
    i = int(near[0])
    arc = arc_lengths(path)
    later = int(np.searchsorted(arc, arc[i] + 5.0))
    joins = later < len(path) and bool(found.distance[later] < PULL_OUT_MEET_M)
    return path, float(arc[i]), float(found.station[i]), joins


@register
class PullOut(BehaviourKind):
    """Pulling out in front of another agent."""

    name = "pull_out"
    spec = BehaviourSpec(
        Behaviour.PULL_OUT, "@{agent} pulls out in front of @{other}", "pull out in front of",
        interaction=InteractionType.MERGING, subtype="merging/pull_out", exact=True,
        conditioned_as=Behaviour.GO_FIRST, first=True,
    )  # fmt: skip
    words = tuple(_PULL_OUT)
    word_rank = 16
    subsumes = ("go_first", "speed_up", "turn_left", "turn_right")
    in_path = True
    judged = staticmethod(judged_by.judge)
    pair_runs = staticmethod(pull_out_runs)

    def target(
        self, ctx: TargetContext, agent: AgentHere, other: AgentHere | None, asked: Mapping[str, float]
    ) -> BehaviourTarget:
        assert other is not None
        return _pull_out(ctx, agent, other)

    def steer(self, target: BehaviourTarget, other_driven: bool) -> list[Steer]:
        """Where it stands until it sets off (`starts_s`), then out onto the other's way: past the meeting point (by
        5 m) when the target has it there (`settled_s`), on its way throughout, at its target speed a second later;
        and, where it joins the other's way, the target's lead ahead of where the other actually drives from then
        (`lead`), so that a pull-out the other closes on is not given up."""
        t, when = target, settled(target)
        starts = steps(t.starts_s or 0.0)
        goal = float(t.station_of_goal or 0.0) + 5.0
        terms = route() + station(goal, "reach", max(when, 10), FUTURE_STEPS, PULL_OUT_REACH_WEIGHT)
        if starts > 0:
            terms += station(0.5, "hold", 1, starts, HOLD_WEIGHT) + speed(0.0, 1, starts)
        terms += speed(float(t.speed or 0.0), starts + steps(1.0))
        if t.lead_m is not None:
            terms += lead(t.lead_m, "reach", when, FUTURE_STEPS, REACH_WEIGHT)
        return terms
