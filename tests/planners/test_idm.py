"""The IDM lane follower on synthetic observations: following, lights, steering, bounds, a short closed loop."""

from __future__ import annotations

import math

import numpy as np
import pytest

from langtraj.env.spaces import MAX_ACCEL, MAX_YAW_RATE, NUM_ROUTE_POINTS, action_space, observation_space
from langtraj.planners import IDMConfig, IDMPlanner
from langtraj.scenario.types import TrafficLightState

from .helpers import left_curve, make_observation, vehicle

FREE = IDMPlanner().act(make_observation(speed=10.0))[0]
"""The acceleration at 10 m/s on an empty straight road."""


def accel(**kwargs) -> float:
    return float(IDMPlanner().act(make_observation(**kwargs))[0])


def test_empty_road_accelerates_toward_the_desired_speed():
    assert 0.0 < FREE <= IDMConfig().max_accel
    assert accel(speed=0.0) == pytest.approx(IDMConfig().max_accel)
    assert accel(speed=IDMConfig().desired_speed) == pytest.approx(0.0, abs=1e-6)
    too_fast = accel(speed=20.0)
    assert -IDMConfig().comfortable_decel <= too_fast < 0.0


def test_brakes_for_a_stopped_or_slower_leader_on_the_route():
    stopped = accel(agents=[vehicle(20.0)])
    slower = accel(agents=[vehicle(40.0, speed=5.0)])
    assert stopped < -2.0
    assert stopped < slower < 0.0
    assert accel(agents=[vehicle(40.0, speed=10.0)]) < FREE  # a leader at the same speed still keeps the gap


def test_the_nearest_obstacle_governs():
    assert accel(agents=[vehicle(60.0), vehicle(15.0)]) == pytest.approx(accel(agents=[vehicle(15.0)]))


def test_ignores_agents_in_the_next_lane_and_behind():
    assert accel(agents=[vehicle(15.0, y=3.5)]) == pytest.approx(FREE)
    assert accel(agents=[vehicle(15.0, y=-3.5)]) == pytest.approx(FREE)
    assert accel(agents=[vehicle(-10.0, speed=15.0)]) == pytest.approx(FREE)


def test_an_agent_overlapping_the_corridor_counts():
    # 2.5 m off the centre: boxes 1 m + 1 m + 0.3 m margin reach 2.3 m, so this one is clear; at 2.2 m it is not
    assert accel(agents=[vehicle(15.0, y=2.5)]) == pytest.approx(FREE)
    assert accel(agents=[vehicle(15.0, y=2.2)]) < -2.0


def test_brakes_for_a_pedestrian_crossing_ahead():
    pedestrian = [15.0, 3.0, np.pi / 2, 0.0, 1.2, 0.5, 0.5]  # walking left, 3 m off the route: clear of it
    assert accel(agents=[pedestrian], agent_types=[2]) == pytest.approx(FREE)
    pedestrian[1] = 0.5  # on the route
    assert accel(agents=[pedestrian], agent_types=[2]) < -2.0


def test_crossing_vehicle_lateral_extent_is_its_length():
    crossing = vehicle(20.0, y=3.0, heading=np.pi / 2)  # 4.5 m long across the route: reaches 0.75 m from it
    assert accel(agents=[crossing]) < 0.0


def test_stops_for_red_lights_on_the_route_only():
    for state in (1, 4, 7):
        assert accel(lights=[(30.0, 0.0, state)]) < 0.0
    assert accel(lights=[(30.0, 0.0, 3)]) == pytest.approx(FREE)  # go
    assert accel(lights=[(30.0, 0.0, 0)]) == pytest.approx(FREE)  # unknown
    assert accel(lights=[(30.0, 3.5, 4)]) == pytest.approx(FREE)  # the next lane's
    assert accel(lights=[(-5.0, 0.0, 4)]) == pytest.approx(FREE)  # behind


def test_caution_stops_only_where_a_comfortable_stop_is_possible():
    for state in TrafficLightState:  # the states' own meaning decides (`is_stop`, `is_caution`), flashing included
        far = accel(lights=[(40.0, 0.0, int(state))])
        assert (far < 0.0) == (state.is_stop or state.is_caution), state
    assert accel(lights=[(40.0, 0.0, int(TrafficLightState.FLASHING_CAUTION))]) < 0.0
    assert accel(lights=[(40.0, 0.0, 5)]) < 0.0  # 10 m/s stops within 25 m
    assert accel(lights=[(12.0, 0.0, 5)]) == pytest.approx(FREE)  # too close: go on
    assert accel(lights=[(12.0, 0.0, 4)]) < -2.0  # but red brakes


def test_steers_along_a_curving_route():
    planner = IDMPlanner()
    assert planner.act(make_observation())[1] == pytest.approx(0.0)
    left = planner.act(make_observation(route=left_curve()))
    right = planner.act(make_observation(route=left_curve() * [1.0, -1.0]))
    assert left[1] > 0.0 and right[1] == pytest.approx(-left[1])
    assert left[1] == pytest.approx(10.0 / 20.0, rel=0.1)  # speed / radius on a circle
    offset = planner.act(make_observation(route=np.array([[0.0, 1.0]]) + make_observation()["route"]))
    assert offset[1] > 0.0  # the route lies left of the ego: steer back onto it


def test_slows_before_a_tight_curve():
    desired = IDMConfig().desired_speed
    assert accel(speed=desired, route=left_curve(radius=15.0)) < 0.0
    assert accel(speed=5.0, route=left_curve(radius=100.0)) > 0.0


def test_drives_at_the_routes_speed_limit_where_the_map_gives_one():
    assert accel(speed=20.0, speed_limits=20.0) == pytest.approx(0.0, abs=1e-6)
    assert accel(speed=IDMConfig().desired_speed, speed_limits=20.0) > 0.5  # not held to the fallback
    assert accel(speed=12.0, speed_limits=8.0) < 0.0
    half = IDMPlanner(IDMConfig(speed_limit_factor=0.5)).act(make_observation(speed=10.0, speed_limits=20.0))[0]
    assert half == pytest.approx(0.0, abs=1e-6)


def test_slows_in_time_for_a_lower_limit_ahead():
    near = np.where(np.arange(NUM_ROUTE_POINTS) < 20, 20.0, 8.0)  # 8 m/s from 40 m on: sqrt(8^2 + 2 b 40) < 20
    far = np.where(np.arange(NUM_ROUTE_POINTS) < 49, 20.0, 8.0)  # from 98 m on: still reachable from 20 m/s
    assert accel(speed=20.0, speed_limits=near) < 0.0
    assert accel(speed=20.0, speed_limits=far) == pytest.approx(0.0, abs=1e-6)
    unknown_ahead = np.where(np.arange(NUM_ROUTE_POINTS) < 20, 20.0, 0.0)  # no limit known further on
    assert accel(speed=20.0, speed_limits=unknown_ahead) == pytest.approx(0.0, abs=1e-6)


def test_brakes_for_a_cut_in_seen_coming():
    heading = float(np.arctan2(-2.5, 15.0))
    merging = [20.0, 3.5, heading, 15.0, -2.5, 4.5, 2.0]  # the next lane, 20 m ahead, 1 s from the ego's
    road = {"speed": 20.0, "speed_limits": 20.0}  # at the limit: no reason to brake but the agent
    assert accel(agents=[merging], **road) < -2.0
    blind = IDMPlanner(IDMConfig(cut_in_horizon=0.0)).act(make_observation(agents=[merging], **road))[0]
    assert blind == pytest.approx(0.0, abs=1e-6)  # where it is now, it is not in the way
    oncoming = [20.0, 3.5, float(np.arctan2(-2.5, -15.0)), -15.0, -2.5, 4.5, 2.0]  # drifting, but the other way
    assert accel(agents=[oncoming], **road) == pytest.approx(0.0, abs=1e-6)


def test_without_a_route_keeps_heading_and_stops_gently():
    action = IDMPlanner().act(make_observation(route=np.zeros((0, 2))))
    assert action[1] == 0.0 and action[0] == pytest.approx(-IDMConfig().comfortable_decel)
    assert IDMPlanner().act(make_observation(speed=0.0, route=np.zeros((0, 2))))[0] == 0.0
    assert IDMPlanner().act(make_observation(route=np.zeros((0, 2)), agents=[vehicle(10.0)]))[0] < -2.0


def test_never_reverses_when_stopped_behind_a_leader():
    action = IDMPlanner().act(make_observation(speed=0.0, agents=[vehicle(5.0)]))
    assert action[0] == 0.0


def test_actions_lie_in_the_action_space():
    rng = np.random.default_rng(0)
    space, planner = action_space("control"), IDMPlanner()
    sampled = observation_space()
    sampled.seed(0)
    for _ in range(50):
        obs = make_observation(
            speed=float(rng.uniform(0, 30)),
            route=np.cumsum(rng.normal(1.0, 1.0, (int(rng.integers(0, 51)), 2)), axis=0),
            agents=[vehicle(*rng.normal(0, 10, 2), speed=float(rng.uniform(0, 20))) for _ in range(8)],
            lights=[(*rng.normal(10, 10, 2), int(rng.integers(0, 9))) for _ in range(4)],
        )
        action = planner.act(obs)
        assert action.dtype == np.float32 and space.contains(action)
    for _ in range(10):  # whatever the space holds (huge values, garbage validity) gives a bounded action
        action = planner.act({key: np.nan_to_num(value) for key, value in sampled.sample().items()})
        assert np.isfinite(action).all() and abs(action[0]) <= MAX_ACCEL and abs(action[1]) <= MAX_YAW_RATE


def _drive(leader_x: float | None = None, light_x: float | None = None, steps: int = 300) -> tuple[float, float]:
    """A 0.1 s unicycle along x under the planner from 10 m/s: (final x, final speed)."""
    planner, x, v = IDMPlanner(), 0.0, 10.0
    for _ in range(steps):
        agents = [] if leader_x is None else [vehicle(leader_x - x)]
        lights = [] if light_x is None else [(light_x - x, 0.0, 4)]
        a = float(planner.act(make_observation(speed=v, agents=agents, lights=lights))[0])
        x, v = x + v * 0.1 + 0.5 * a * 0.01, max(0.0, v + a * 0.1)
    return x, v


def test_closed_loop_stops_behind_a_stopped_leader_and_before_a_red_light():
    x, v = _drive(leader_x=60.0)
    gap = 60.0 - x - 4.5
    assert v < 0.05 and 0.5 < gap < IDMConfig().min_gap + 0.5
    x, v = _drive(light_x=50.0)
    assert v < 0.05 and 50.0 - 2.25 - IDMConfig().min_gap - 0.5 < x < 50.0 - 2.25


def test_repeated_route_points_change_nothing():
    route = np.repeat(left_curve()[:25], 2, axis=0)
    np.testing.assert_array_equal(
        IDMPlanner().act(make_observation(route=route)), IDMPlanner().act(make_observation(route=left_curve()[:25]))
    )


def test_the_cautious_planner_brakes_for_what_the_idm_passes_and_earlier():
    """An agent straddling the lane line 2.4 m off the route, and one 4.5 m off drifting in at 1.2 m/s (in the
    path within 2 s): the IDM lets both by, the cautious planner brakes; for the same leader it brakes harder."""
    from langtraj.planners import CautiousPlanner, load_planner

    assert load_planner("cautious") is CautiousPlanner

    def cautious(**kwargs) -> float:
        return float(CautiousPlanner().act(make_observation(**kwargs))[0])

    straddling = [vehicle(15.0, y=2.4)]
    assert accel(agents=straddling) == pytest.approx(FREE) and cautious(agents=straddling) < 0.0
    merging = [vehicle(20.0, y=4.5, speed=8.0, heading=-0.15)]
    assert accel(agents=merging) == pytest.approx(FREE) and cautious(agents=merging) < 0.0
    assert cautious(agents=[vehicle(40.0, speed=10.0)]) < accel(agents=[vehicle(40.0, speed=10.0)])


def test_the_cautious_planner_brakes_for_a_car_crossing_its_way_seen_coming_and_not_for_oncoming_traffic():
    """A car 20 m ahead and 20 m to the side driving across the route at 10 m/s (on it in 2 s, as a red-light runner
    comes): the IDM, which looks only at agents heading its way, keeps going; the cautious planner brakes. Oncoming
    traffic in the next lane it lets by."""
    from langtraj.planners import CautiousPlanner

    def cautious(**kwargs) -> float:
        return float(CautiousPlanner().act(make_observation(**kwargs))[0])

    crossing = [vehicle(20.0, y=-20.0, speed=10.0, heading=math.pi / 2)]
    assert accel(agents=crossing) == pytest.approx(FREE) and cautious(agents=crossing) < -1.0
    leaving = [vehicle(20.0, y=5.0, speed=10.0, heading=math.pi / 2)]  # across already, driving away
    oncoming = [vehicle(30.0, y=3.5, speed=10.0, heading=math.pi)]
    free = cautious()
    assert cautious(agents=leaving) == pytest.approx(free) and cautious(agents=oncoming) == pytest.approx(free)
