"""Pulling over to the kerb and stopping: in the lane next to the kerb, the lane ahead shifted toward the kerb and a
stop where gentle braking brings the agent to rest (past the next junction where the kerb before it is too near);
judged by the labelers' pulling-over label. See docs/interdrive.md ('Targets and feasibility')."""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from langtraj.interdrive.behaviour import Behaviour, BehaviourSpec
from langtraj.interdrive.behaviours.base import BehaviourKind, Steer, register, route, steps
from langtraj.interdrive.behaviours.recipes import stand, stop_step
from langtraj.interdrive.reader.words import OBJ, gap, verb
from langtraj.interdrive.targets.context import COMFORT_DECELERATION, HORIZON_S, AgentHere, TargetContext
from langtraj.interdrive.targets.target import BehaviourTarget, TargetUnavailable
from langtraj.polylines import arc_lengths, point_at
from langtraj.roads import MapIndex
from langtraj.roads.routes import ROUTE_SPACING
from langtraj.roads.routes import route as lane_route

KERB_PAST_JUNCTION_M = 12.0
"""How far past a junction's exit a pull-over stops when the kerb before the junction is too near (m): room to move
across after leaving the junction lane."""
PULL_OVER_DECELERATION = 1.5
"""Braking a pull-over is planned with (m/s^2): gentler, as it also moves sideways."""
KERB_CLEARANCE = 0.4
"""Gap a pulled-over vehicle's side is asked to leave to the road edge (m), where the road is wide enough."""
KERB_MIN_CLEARANCE = 0.1
"""The least gap to the road edge a pull-over is asked for (m), where the lane is too narrow for both
`KERB_CLEARANCE` and the target's least shift of 0.8 m."""
KERB_SEARCH_M = 8.0
"""How far to the right of its lane a pull-over looks for the road edge (m)."""

# ---------------------------------------------------------------------------------------------- words

_PLACE = (
    r"(?:side\s+of\s+the\s+(?:road|street)|roadside|road\s+side|kerb|curb|kerbside|curbside|hard\s+shoulder"
    r"|shoulder|verge|edge\s+of\s+the\s+(?:road|street)|lay-by|layby)"
)
_TO_THE_SIDE = verb(
    "move", "steer", "head", "go", "get", "pull", "drive", "ease", "edge", "tuck", "draw", "swing", "park", "stop",
    "halt", "come", "bring it", "roll", "coast", "nose", "bear",
)  # fmt: skip
_PULL_OVER = [
    rf"\b{verb('pull')}{OBJ}\s+(?:over|in|off|aside)\b"
    r"(?!\s+(?:behind|in\s+front|ahead|between|next\s+to|alongside)\b|[^,;.]{0,25}\blanes?\b)",
    rf"\b{_TO_THE_SIDE}"
    rf"{gap(5)}\s+(?:at|by|on|onto|to|towards|against|beside|alongside|into|next\s+to|near)"
    rf"\s+(?:the\s+|a\s+)?(?:near\s+|left\s+|right\s+|nearside\s+|left-hand\s+|right-hand\s+)?{_PLACE}\b",
    rf"\b(?:onto|towards?)\s+(?:the\s+)?{_PLACE}\b",
]

# ---------------------------------------------------------------------------------------------- target


def _pull_over(ctx: TargetContext, agent: AgentHere) -> BehaviourTarget:
    """The agent moves in the lane next to the kerb on its right (the rightmost or only lane) with room to stop
    comfortably before the next junction (the labeler does not call a stop at a junction a pull-over): the lane ahead
    shifted to the right, to the kerb (`kerb_distance`, less half the width and `KERB_CLEARANCE`, at least 0.8 m off
    the centre, but never nearer the edge than `KERB_MIN_CLEARANCE`) or half a lane where the map has no road
    edges, and a stop where gentle braking brings it to rest."""
    index, behaviour = ctx.index, Behaviour.PULL_OVER
    if not ctx.moving(agent):
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", "it is (nearly) stopped at the current step")
    ctx.need_lane(agent, behaviour, "lane position")
    position = index.lane_position(agent.here.lane, agent.here.station)
    if position == "unknown":
        reason = (
            "the map has no lane neighbour information"
            if index.neighbor_source == "none"
            else "it is inside a junction, where lanes have no neighbours"
        )
        raise TargetUnavailable(agent.track_id, behaviour, "undecided", reason)
    if position not in ("rightmost", "single"):
        reason = "a lane lies on its right: it is not in the lane next to the kerb"
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
    v = agent.here.speed
    room = v**2 / (2 * COMFORT_DECELERATION) + ctx.config.heuristics.pull_over_junction_distance
    junction = index.distance_to_junction(agent.here.lane, agent.here.station) if index.has_connectivity else math.inf
    if junction >= room:
        lane_path = ctx.ahead(agent)
        stop = max(v * v / (2 * PULL_OVER_DECELERATION), 2.0 * v, 8.0)
        stop = min(stop, max(0.5 * v * 5.5, 8.0))
        begin, where = min(max(0.3 * stop, 3.0), stop), ""
    else:
        near = f"the next junction is {junction:.0f} m ahead, too close to stop at the kerb before it"
        lane_path, stop, begin, why_not = _kerb_past_junction(ctx, agent)
        if why_not:
            raise TargetUnavailable(agent.track_id, behaviour, "infeasible", f"{near}, and {why_not}")
        where = f" past the junction {junction:.0f} m ahead"
    point = point_at(lane_path, stop)
    offset, reason = 1.2, "half a lane to its right (the map has no road edges)"
    if index.has_road_edges:
        k = min(int(stop / ROUTE_SPACING), len(lane_path) - 2)
        d = lane_path[k + 1] - lane_path[k]
        kerb = kerb_distance(index, point, np.array([d[1], -d[0]]) / max(float(np.linalg.norm(d)), 1e-9))
        if kerb is None:
            reason = f"half a lane to its right (no road edge within {KERB_SEARCH_M:.0f} m of its lane)"
        else:
            beside = kerb - 0.5 * agent.width  # how far its centre can move right before its side meets the edge
            offset = float(min(np.clip(beside - KERB_CLEARANCE, 0.8, 3.0), beside - KERB_MIN_CLEARANCE))
            if offset < ctx.config.heuristics.pull_over_min_lane_offset:
                reason = f"the road edge is {kerb:.1f} m to its right: no room beside its lane to pull over"
                raise TargetUnavailable(agent.track_id, behaviour, "infeasible", reason)
            reason = f"the kerb {kerb:.1f} m to its right"
    arc = arc_lengths(lane_path)
    shift = offset * np.clip((arc - begin) / max(stop - begin, 1.0), 0.0, 1.0)
    tangent = np.gradient(lane_path, axis=0)
    tangent /= np.maximum(np.linalg.norm(tangent, axis=1, keepdims=True), 1e-9)
    right = np.stack([tangent[:, 1], -tangent[:, 0]], -1)
    return BehaviourTarget(
        agent.track_id,
        behaviour,
        lane_path + shift[:, None] * right,
        f"a stop {stop:.0f} m ahead{where}, {reason}",
        station_of_goal=float(stop),
        speed=0.0,
        current_speed=v,
    )


def _kerb_past_junction(ctx: TargetContext, agent: AgentHere) -> tuple[np.ndarray, float, float, str]:
    """The next kerb a driver would use when the one before the junction is too near: through the junction on its
    straightest branch into a kerb lane (the rightmost or only one) and `KERB_PAST_JUNCTION_M` past its exit, with
    room before the lane's own next junction, reached braking at no more than `COMFORT_DECELERATION` and within the
    horizon (driving on at its speed, then braking at `PULL_OVER_DECELERATION`). Gives the path, the stop station,
    where the move toward the kerb begins, and why there is no such kerb (empty when there is)."""
    index, v = ctx.index, agent.here.speed
    branches = ctx.junction(agent).branches
    if not branches:
        return np.zeros((0, 2)), 0.0, 0.0, "no way through it on the map"
    branch = min(branches, key=lambda b: (abs(b.turn), b.exit_at))
    exits = [e for e in index.exits[branch.lanes[-1]] if not index.is_junction[e]]
    if not exits:
        return np.zeros((0, 2)), 0.0, 0.0, "its way through the junction leads into no road lane"
    lane = exits[0]
    if index.lane_position(lane, 0.0) not in ("rightmost", "single"):
        return np.zeros((0, 2)), 0.0, 0.0, "its lane past the junction has a lane on its right"
    stop = max(branch.exit_at + KERB_PAST_JUNCTION_M, v * v / (2 * COMFORT_DECELERATION))
    braking = min(v * v / (2 * PULL_OVER_DECELERATION), stop)
    if (stop - braking) / max(v, 0.1) + 2 * braking / max(v, 0.1) > HORIZON_S:
        why = f"the kerb past it ({stop:.0f} m ahead) is beyond its reach in {HORIZON_S:g} s"
        return np.zeros((0, 2)), 0.0, 0.0, why
    beyond = index.distance_to_junction(lane, 0.0) - (stop - branch.exit_at)
    if beyond < ctx.config.heuristics.pull_over_junction_distance:
        return np.zeros((0, 2)), 0.0, 0.0, "the road past it reaches another junction too soon"
    path = lane_route(index, (*branch.lanes, lane), agent.here.station, max(agent.reach, stop + 20.0))
    return path, stop, branch.exit_at + 2.0, ""


def kerb_distance(index: MapIndex, point: np.ndarray, direction: np.ndarray) -> float | None:
    """How far from `point` along the unit `direction` the first road edge lies (m; None: none within
    `KERB_SEARCH_M`): sphere tracing, each step the distance to the nearest edge, so the ray never passes one."""
    travelled = 0.0
    for _ in range(64):  # a ray grazing an edge crawls: after 64 steps it is within centimetres of one
        gap = float(index.distance_to_road_edge(point + travelled * direction, KERB_SEARCH_M)[0])
        if not math.isfinite(gap):
            return None
        if gap < 0.02:
            return travelled
        travelled += gap
        if travelled > KERB_SEARCH_M:
            return None
    return travelled


@register
class PullOver(BehaviourKind):
    """Pulling over to the side of the road and stopping."""

    name = "pull_over"
    spec = BehaviourSpec(
        Behaviour.PULL_OVER, "@{agent} pulls over to the side of the road and stops", "pull over", "pulling_over"
    )
    words = tuple(_PULL_OVER)
    word_rank = 8
    subsumes = ("stop", "slow_down")

    def target(
        self, ctx: TargetContext, agent: AgentHere, other: AgentHere | None, asked: Mapping[str, float]
    ) -> BehaviourTarget:
        return _pull_over(ctx, agent)

    def steer(self, target: BehaviourTarget, other_driven: bool) -> list[Steer]:
        """On the kerb line from 2 s on, never past the stop point, standing still from when even braking gets
        there (at most 5.5 s, so the stop lasts the 2 s the labeler asks)."""
        return route(first=steps(2.0)) + stand(target, min(stop_step(target), steps(5.5)))
