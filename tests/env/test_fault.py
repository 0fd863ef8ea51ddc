"""Right of way in fault (`env.fault.gives_way_to_ego`, docs/testing.md, 'Step info'): at a junction, a car turning
across the road the ego keeps, or one coming off the road, owes the ego the right of way; the ego turning across a
road is the one that gives way."""

from __future__ import annotations

import math

import numpy as np
from interdrive.test_counterfactual import LEFT_TURN, four_way

from langtraj.env.fault import CollisionKind, at_fault, collision_kind, gives_way_to_ego
from langtraj.metrics.interaction import pair_signed_distance
from langtraj.roads import MapIndex

INDEX = MapIndex.build(four_way())  # junction lanes: 42 eastbound straight (y = -1.75), 11 a left turn north to west


def _box(x: float, y: float, heading: float, speed: float) -> np.ndarray:
    return np.array([x, y, heading, 4.5, 2.0, speed * math.cos(heading), speed * math.sin(heading)])


def _first_contact(mover, other: np.ndarray, start: float) -> np.ndarray:
    """`mover(s)` (a box along its way at s) at the first s from `start` on, every 5 cm, whose box touches `other`."""

    def gap(s: float) -> float:
        return float(pair_signed_distance(*(np.array(v) for v in mover(s)[:5]), *(np.array(v) for v in other[:5])))

    s = start
    while s < start + 40.0 and gap(s) >= 0:
        s += 0.05
    return mover(s)


def _turning_car() -> np.ndarray:
    k = int(np.argmin(np.abs(LEFT_TURN[:, 1] + 1.75)))  # where the left turn crosses the eastbound lane
    d = LEFT_TURN[k + 1] - LEFT_TURN[k - 1]
    return _box(*LEFT_TURN[k, :2], math.atan2(d[1], d[0]), 5.0)


def test_a_car_turning_across_the_road_the_ego_keeps_is_not_the_egos_fault():
    turning = _turning_car()
    ego = _first_contact(lambda s: _box(-20.0 + s, -1.75, 0.0, 8.0), turning, 0.0)  # straight on, eastbound
    kind = collision_kind(ego, turning, INDEX)
    assert kind is CollisionKind.CROSSED and not at_fault(kind, left_lane=False)
    assert at_fault(kind, left_lane=True)  # unless the ego had left its lane


def test_the_ego_turning_across_a_road_gives_way_and_a_straight_crossing_stays_its_own():
    turning_ego = _turning_car()
    through = _box(-8.0, -1.75, 0.0, 8.0)  # eastbound on lane 42
    assert gives_way_to_ego(INDEX, through, turning_ego)  # the turning car gives way to the through one ...
    assert not gives_way_to_ego(INDEX, turning_ego, through)  # ... so when the ego turns, the through car does not
    crossing = _box(-1.75, -1.75, 0.0, 8.0)  # eastbound on lane 42, straight across the northbound lane
    ego = _first_contact(lambda s: _box(-1.75, -12.0 + s, math.pi / 2, 8.0), crossing, 0.0)  # straight on, lane 12
    assert collision_kind(ego, crossing, INDEX) is CollisionKind.FRONT  # no right of way read: the ego's to avoid


def test_a_car_coming_off_the_road_is_not_the_egos_fault():
    from_driveway = _box(-36.5, -4.5, math.pi / 2, 3.0)  # its centre 2.75 m south of lane 41, across it: no lane
    ego = _first_contact(lambda s: _box(-50.0 + s, -1.75, 0.0, 8.0), from_driveway, 0.0)
    ego[0] += 0.5  # half a metre into it: its bumper on the other's side
    kind = collision_kind(ego, from_driveway, INDEX)  # coming across from off its lane: the cut-in rule's side contact
    assert kind is CollisionKind.LATERAL and not at_fault(kind, left_lane=False)
    assert gives_way_to_ego(INDEX, ego, from_driveway)  # and it owed the ego the right of way
