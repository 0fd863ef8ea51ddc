"""Who caused a collision of the ego, by category after nuPlan's at-fault collisions (docs/testing.md, 'Step info'):
an ego standing still is never at fault; driving into an agent that stands still, or with its front bumper into
one ahead in its lane, it is; hit from behind, it is not; a side contact is the fault of whoever left their lane,
judged on the ego: it is at fault when its box reaches out of the lane it is on (or it is on no lane at all)
(`left_its_lane`). A contact at the ego's bumper with an agent that is itself out of its lane and coming across toward
the ego (a cut-in landing on the bumper) is a side contact too; one drifting away is still the ego's to avoid.

Right of way, beyond nuPlan, where the two cross paths (`right_of_way`): from the signals and signs each passed
(`env.right_of_way`), else from the lanes (the agent turning across the road the other keeps, or coming from off the
road, gives way). An ego that owed the way is at fault (`CollisionKind.OWED`); an agent that owed it to the ego is
not the ego's fault unless the ego left its lane (`CollisionKind.CROSSED`)."""

from __future__ import annotations

import math
from enum import StrEnum

import numpy as np

from langtraj.env.right_of_way import Basis, RightOfWay
from langtraj.metrics.features import COLLISION_THRESHOLD
from langtraj.metrics.interaction import pair_signed_distance
from langtraj.roads import MapIndex
from langtraj.roads.position import LANE_MATCH_MAX_HEADING, LANE_MATCH_RADIUS
from langtraj.scenario.drivable import DEFAULT_LANE_WIDTH_M

STOPPED_SPEED = 0.5
"""An agent slower than this (m/s) stands still: an ego that does causes nothing; one that hits such an agent does."""
REAR_BEARING = math.radians(150.0)
"""An agent whose centre lies more than this angle off the ego's heading is behind it (nuPlan's rear test)."""
BUMPER_DEPTH_M = 0.1
"""The ego's front bumper: a strip this deep across its front edge."""
LANE_TOLERANCE_M = 0.3
"""How far past its lane's side the ego's box may reach before it counts as out of its lane."""
CROSSING_SPEED = 0.2
"""An agent moving sideways toward the ego's centreline faster than this (m/s, relative to the ego) comes across."""
CROSSING_ANGLE = math.radians(45.0)
"""An agent heading more than this off the ego's heading crosses its path rather than drives ahead of it."""
TURNING_LANE_ANGLE = math.radians(30.0)
"""A lane whose heading turns by more than this from its start to its end is a turn (a junction's turning lane)."""


class CollisionKind(StrEnum):
    """How the ego met the agent it collided with (nuPlan's categories)."""

    STOPPED_EGO = "stopped_ego"  # the ego stood still: not at fault
    STOPPED_OTHER = "stopped_other"  # the ego drove into an agent standing still: at fault
    REAR = "rear"  # the other came from behind: not at fault
    FRONT = "front"  # the ego's front bumper struck it, ahead in its lane: at fault
    LATERAL = "lateral"  # a side contact: at fault when the ego left its lane
    CROSSED = "crossed"  # it crossed the ego's path owing it the right of way: at fault when the ego left its lane
    OWED = "owed"  # the ego crossed its path owing it the right of way: at fault


def collision_kind(
    ego: np.ndarray, other: np.ndarray, index: MapIndex | None = None, way: RightOfWay | None = None
) -> CollisionKind:
    """The kind of a contact between the ego's box and another's (x, y, heading, length, width, vx, vy each);
    `index`, the map's lanes, tells a bumper contact with an agent cutting in (lateral) from one with an agent
    ahead; `way`, who owed whom the right of way where their paths cross (`right_of_way`), makes the ego's front or
    side contact `OWED` when the ego owed it, a front contact `CROSSED` when the other did."""
    if math.hypot(ego[5], ego[6]) < STOPPED_SPEED:
        return CollisionKind.STOPPED_EGO
    if math.hypot(other[5], other[6]) < STOPPED_SPEED:
        return CollisionKind.STOPPED_OTHER
    x, y, heading, length, width = (float(v) for v in ego[:5])
    cos, sin = math.cos(heading), math.sin(heading)
    along = (other[0] - x) * cos + (other[1] - y) * sin
    beside = -(other[0] - x) * sin + (other[1] - y) * cos  # left positive
    sideways = -(other[5] - ego[5]) * sin + (other[6] - ego[6]) * cos  # its velocity across the ego's heading
    bearing = math.atan2(other[1] - y, other[0] - x) - heading
    if abs(math.remainder(bearing, 2 * math.pi)) > REAR_BEARING:
        return CollisionKind.REAR
    if way is not None and way.ego_owed:
        return CollisionKind.OWED
    ahead = length / 2 - BUMPER_DEPTH_M / 2
    bumper = pair_signed_distance(
        np.array(x + ahead * math.cos(heading)), np.array(y + ahead * math.sin(heading)), np.array(heading),
        np.array(BUMPER_DEPTH_M), np.array(width), *(np.array(float(v)) for v in other[:5]),
    )  # fmt: skip
    if float(bumper) >= COLLISION_THRESHOLD or along <= length / 2:  # not at the bumper, or its centre alongside
        return CollisionKind.LATERAL
    coming = beside * sideways < 0 and abs(sideways) > CROSSING_SPEED
    if coming and left_its_lane(index, other) and not left_its_lane(index, ego):  # it cut in onto the bumper
        return CollisionKind.LATERAL
    if way is not None:
        return CollisionKind.CROSSED
    return CollisionKind.FRONT


def right_of_way(
    index: MapIndex | None, ego: np.ndarray, other: np.ndarray, passed: RightOfWay | None = None
) -> RightOfWay | None:
    """Who of the ego and the other (boxes as `collision_kind`'s) owed the other the right of way, where their paths
    cross (headings more than `CROSSING_ANGLE` apart; None otherwise): `passed`, what the signals and signs they
    passed say (`env.right_of_way.Passings`), when it says anything; else the lanes (`gives_way`); else None (two
    roads crossing straight with neither signal nor sign: the ego's to avoid, as nuPlan's front collisions)."""
    if abs(math.remainder(float(other[2]) - float(ego[2]), 2 * math.pi)) <= CROSSING_ANGLE:
        return None
    if passed is not None:
        return passed
    if gives_way(index, keeper=ego, crosser=other):
        return RightOfWay(ego_owed=False, basis=Basis.LANES)
    if gives_way(index, keeper=other, crosser=ego):
        return RightOfWay(ego_owed=True, basis=Basis.LANES)
    return None


def gives_way(index: MapIndex | None, *, keeper: np.ndarray, crosser: np.ndarray) -> bool:
    """Whether `crosser`, crossing `keeper`'s path, had to give way to it by the lanes: `keeper` keeps its road (on a
    lane that does not turn) while `crosser` turns across it (on a turning lane) or comes from off the road (on no
    lane: a driveway, the kerb)."""
    if index is None or not index.has_lanes:
        return False
    mine = _lane_of(index, keeper)
    if mine is None or _turns(index, mine):
        return False
    theirs = _lane_of(index, crosser)
    return theirs is None or _turns(index, theirs)


def _lane_of(index: MapIndex, box: np.ndarray) -> int | None:
    """The lane the labelers would put an agent's box on (within 3 m and 45 degrees), or None."""
    match = index.match_lanes(
        np.array([[float(box[0]), float(box[1])]]),
        np.array([float(box[2])]),
        radius=LANE_MATCH_RADIUS,
        max_heading_diff=LANE_MATCH_MAX_HEADING,
    )
    return int(match.lane[0]) if match.matched[0] else None


def _turns(index: MapIndex, lane: int) -> bool:
    end = index.heading_at(lane, float(index.lane_lengths[lane]))
    return abs(math.remainder(end - index.heading_at(lane, 0.0), 2 * math.pi)) > TURNING_LANE_ANGLE


def left_its_lane(index: MapIndex | None, box: np.ndarray) -> bool | None:
    """Whether an agent's box (x, y, heading, length, width, ...) reaches out of the lane it is on by more than
    `LANE_TOLERANCE_M`, or it is on no lane near its heading; None where the map has no lanes (nothing to judge)."""
    if index is None or not index.has_lanes:
        return None
    x, y, heading, _, width = (float(v) for v in box[:5])
    match = index.match_lanes(  # the lane the labelers would put it on
        np.array([[x, y]]), np.array([heading]), radius=LANE_MATCH_RADIUS, max_heading_diff=LANE_MATCH_MAX_HEADING
    )
    if not match.matched[0]:
        return True
    return bool(abs(match.lateral[0]) + width / 2 > DEFAULT_LANE_WIDTH_M / 2 + LANE_TOLERANCE_M)


def at_fault(kind: CollisionKind, left_lane: bool | None) -> bool:
    """Whether the ego caused a contact of `kind` (`left_lane`: `left_its_lane`; a side contact where the map has no
    lanes is not the ego's)."""
    if kind in (CollisionKind.STOPPED_OTHER, CollisionKind.FRONT, CollisionKind.OWED):
        return True
    return kind in (CollisionKind.LATERAL, CollisionKind.CROSSED) and bool(left_lane)
