"""The environment's judges on constructed scenes (docs/testing.md, 'Step info'): time to collision against its
closed form, collisions and who caused them, off-road at a road edge, and the reward's terms."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scenario_builders import two_lane_road

from langtraj.env.events import EventJudge
from langtraj.env.fault import STOPPED_SPEED
from langtraj.env.reward import RewardConfig
from langtraj.errors import InputError
from langtraj.metrics.interaction import MAX_TTC
from langtraj.metrics.road import road_edge_index
from langtraj.roads import MapIndex
from langtraj.scenario.drivable import measured_road_edges
from langtraj.scenario.types import StateField

# two_lane_road's cars are 4.5 m long and 2 m wide; its road edges lie at y = -1.75 and y = 5.25.
LENGTH, WIDTH, EDGE = 4.5, 2.0, -1.75


def judged(cars: list[tuple[float, ...]], *, heading: float = 0.0):
    """The ego's (the first car's) events among `cars` (x, y, speed and optionally its own heading; else every car
    heading `heading`) and a car parked far ahead in the other lane, at the current step of a two-lane road, judged
    against its road edges and lanes."""
    cars = [*cars, (250.0, 3.5, 0.0)]
    scenario = two_lane_road([car[:3] for car in cars])
    edges = road_edge_index([f.points for f in measured_road_edges(scenario)])  # as the environment builds it
    states = scenario.agents.states[:, scenario.current_index].copy()
    for row, (x, y, speed, *turned) in enumerate(cars):
        h = turned[0] if turned else heading
        states[row, StateField.X], states[row, StateField.Y] = x, y
        states[row, StateField.HEADING] = h
        states[row, StateField.VX], states[row, StateField.VY] = speed * math.cos(h), speed * math.sin(h)
    index = MapIndex.build(scenario.road_map)
    return EventJudge(scenario, 0, edges, index).judge(states, np.ones(len(cars), bool))


def test_time_to_collision_is_the_bumper_gap_over_the_closing_speed():
    gap = 20.0 - LENGTH  # centres 20 m apart: 15.5 m bumper to bumper
    assert judged([(0.0, 0.0, 10.0), (20.0, 0.0, 5.0)]).ttc == pytest.approx(gap / 5.0)
    assert judged([(0.0, 0.0, 10.0), (20.0, 0.0, 12.0)]).ttc == MAX_TTC  # pulling away: never
    assert judged([(0.0, 0.0, 10.0), (20.0, 3.5, 0.0)]).ttc == MAX_TTC  # in the other lane: not followed
    assert judged([(0.0, 0.0, 10.0), (-20.0, 0.0, 20.0)]).ttc == MAX_TTC  # behind: not followed


def test_the_gap_to_the_nearest_box_and_who_is_hit():
    apart = judged([(0.0, 0.0, 10.0), (10.0, 0.0, 10.0), (30.0, 3.5, 10.0)])
    assert apart.min_distance == pytest.approx(10.0 - LENGTH)
    assert not apart.collision and apart.collided_with == () and not apart.at_fault
    hit = judged([(0.0, 0.0, 10.0), (4.0, 0.0, 3.0), (30.0, 3.5, 10.0)])  # 0.5 m into the car ahead
    assert hit.collided_with == (2,) and hit.min_distance == pytest.approx(-0.5)


def _kinds(events) -> list[tuple[int, str, bool]]:
    return [(c.partner, c.kind.value, c.at_fault) for c in events.contacts]


def test_fault_goes_by_the_kind_of_contact():
    # the ego rear-ends a slower lead with its front bumper: at fault
    assert _kinds(judged([(0.0, 0.0, 10.0), (4.0, 0.0, 3.0)])) == [(2, "front", True)]
    # the ego drives into a car standing still: at fault, whatever part touches
    assert _kinds(judged([(0.0, 0.0, 10.0), (4.0, 0.0, 0.0)])) == [(2, "stopped_other", True)]
    # a stopped ego hit from behind: not at fault; so too a moving one run into from behind
    standing = judged([(0.0, 0.0, STOPPED_SPEED / 2), (-4.0, 0.0, 10.0)])
    assert standing.collision and _kinds(standing) == [(2, "stopped_ego", False)] and not standing.at_fault
    assert _kinds(judged([(0.0, 0.0, 3.0), (-4.0, 0.0, 10.0)])) == [(2, "rear", False)]


def test_a_side_contact_is_the_fault_of_whoever_left_their_lane():
    # the other drifts out of the left lane (centre y = 3.5) into the ego, which keeps its lane's centre
    drifted = judged([(0.0, 0.0, 10.0), (1.0, 1.9, 10.0)])
    assert _kinds(drifted) == [(2, "lateral", False)] and drifted.collision and not drifted.at_fault
    # the ego drifts out of its lane into a car keeping the centre of the left lane
    assert _kinds(judged([(0.0, 1.6, 10.0), (1.0, 3.5, 10.0)])) == [(2, "lateral", True)]
    # a little off its centre, its box 0.3 m past its lane's side at most: still in its lane
    assert _kinds(judged([(0.0, 0.3, 10.0), (1.0, 2.2, 10.0)])) == [(2, "lateral", False)]
    # a cut-in landing on the ego's bumper, the other across both lanes and coming across: its doing
    assert _kinds(judged([(0.0, 0.0, 10.0), (3.5, 1.2, 9.0, -0.3)])) == [(2, "lateral", False)]
    # the same car drifting away out of the ego's lane as the ego runs into it: the ego's to avoid
    assert _kinds(judged([(0.0, 0.0, 10.0), (3.5, 1.2, 9.0, 0.3)])) == [(2, "front", True)]
    # the same car once in the ego's lane: the ego drove into it
    assert _kinds(judged([(0.0, 0.0, 10.0), (4.3, 0.2, 9.0)])) == [(2, "front", True)]


def test_off_road_is_the_box_past_the_edge_not_its_centre():
    inside = EDGE + WIDTH / 2 + 0.05  # its right side 5 cm inside the edge
    assert not judged([(0.0, inside, 10.0)]).offroad
    assert judged([(0.0, inside - 0.1, 10.0)]).offroad  # its side 5 cm past it, the centre on the road
    across = EDGE + LENGTH / 2 + 0.1  # turned across the lane, its tail 10 cm inside the edge
    assert not judged([(0.0, across, 10.0)], heading=math.pi / 2).offroad
    assert judged([(0.0, across - 0.2, 10.0)], heading=math.pi / 2).offroad  # its tail 10 cm past it


def test_no_edges_nothing_is_off_road():
    scenario = two_lane_road([(0.0, -10.0, 10.0), (250.0, 3.5, 0.0)])  # the ego wholly past the edge
    states = scenario.agents.states[:, scenario.current_index]
    assert not EventJudge(scenario, 0, None).judge(states, np.ones(2, bool)).offroad


def test_the_reward_is_progress_minus_each_penalty_once():
    config = RewardConfig(progress=0.1, collision=5.0, at_fault_collision=2.0, offroad=1.0)
    assert config.reward(10.0, False, False, False) == pytest.approx(1.0)
    assert config.reward(10.0, True, False, False) == pytest.approx(1.0 - 5.0)
    assert config.reward(10.0, True, True, False) == pytest.approx(1.0 - 5.0 - 2.0)
    assert config.reward(10.0, False, True, True) == pytest.approx(1.0 - 1.0)  # at fault without a collision: none
    assert config.reward(-2.0, False, False, False) == pytest.approx(-0.2)  # losing ground costs


def test_a_reward_weight_that_is_not_a_finite_number_is_refused():
    with pytest.raises(InputError, match=r"reward\.offroad"):
        RewardConfig(offroad=math.nan)
    with pytest.raises(InputError, match=r"reward\.progress"):
        RewardConfig(progress="fast")  # type: ignore[arg-type]
