"""The ego against the rules of the road (`env.rules`, docs/testing.md, 'What an episode measures'): a red light run
with the lights replayed from the log or held at the start, driving against the lane, the speed limit; and the
episode's comfort figures against nuPlan's bounds."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scenario_builders import two_lane_road

from langtraj.env.rules import EpisodeLights, RuleJudge
from langtraj.roads import MapIndex
from langtraj.roads.mission import Route
from langtraj.scenario import TrafficLights
from langtraj.scenario.types import StateField, TrafficLightState
from langtraj.suites.verdict import COMFORT_BOUNDS, StepRecord, comfort_figures

STOP_X = 20.0  # the signal's stop point on the right lane (feature 10)


def _signalled(turns_red_at: int):
    """The two-lane road with a signal on its right lane at x = 20: green, then red from step `turns_red_at`."""
    scenario = two_lane_road([(0.0, 0.0, 10.0), (200.0, 3.5, 0.0)])
    states = np.full((scenario.num_steps, 1), int(TrafficLightState.GO), np.int8)  # one signal
    states[turns_red_at:] = int(TrafficLightState.STOP)
    lights = TrafficLights(np.array([10]), states, np.ones_like(states, bool), np.array([[STOP_X, 0.0, 0.0]]))
    return replace(scenario, traffic_lights=lights)


def _state(x: float, y: float = 0.0, heading: float = 0.0, speed: float = 10.0) -> np.ndarray:
    state = np.zeros(9, np.float32)
    state[[StateField.X, StateField.Y, StateField.HEADING]] = x, y, heading
    state[StateField.VX], state[StateField.VY] = speed * np.cos(heading), speed * np.sin(heading)
    return state


def _judge(scenario, lights: str, limit: float = np.nan) -> RuleJudge:
    points = np.stack([np.linspace(-50, 250, 301), np.zeros(301)], axis=1)
    route = Route.of(points, "lanes", np.array([limit]), np.array([300.0]))
    return RuleJudge(scenario, 0, MapIndex.build(scenario.road_map), route, EpisodeLights(scenario, lights))


@pytest.mark.parametrize(("lights", "red"), [("log", True), ("held", False)])
def test_crossing_a_light_that_turned_red_is_a_red_light_run_with_the_log_replayed(lights, red):
    scenario = _signalled(turns_red_at=15)  # green at the start (step 10), red from step 15
    judge = _judge(scenario, lights)
    assert judge.judge(_state(STOP_X - 0.5), _state(STOP_X + 0.5), 20, 70.0).red_light is red
    assert not judge.judge(_state(STOP_X - 1.5), _state(STOP_X - 0.5), 20, 70.0).red_light  # short of the line
    assert not judge.judge(_state(STOP_X - 0.5), _state(STOP_X + 0.5), 12, 70.0).red_light  # still green then


def test_driving_against_the_lane_and_over_the_limit():
    judge = _judge(two_lane_road([(0.0, 0.0, 10.0), (200.0, 3.5, 0.0)]), "log", limit=8.0)
    events = judge.judge(_state(0.0), _state(1.0), 11, 51.0)
    assert not events.wrong_way and events.over_limit == pytest.approx(2.0, abs=1e-6)
    against = judge.judge(_state(1.0, heading=np.pi), _state(0.0, heading=np.pi), 11, 50.0)
    assert against.wrong_way
    assert not judge.judge(
        _state(1.0, heading=np.pi, speed=0.2), _state(1.0, heading=np.pi, speed=0.2), 11, 50.0
    ).wrong_way
    assert (
        _judge(two_lane_road([(0.0, 0.0, 10.0), (200.0, 3.5, 0.0)]), "log")
        .judge(_state(0.0), _state(1.0), 11, 51.0)
        .over_limit
        is None
    )


def test_comfort_figures_hold_the_executed_controls_to_nuplans_bounds():
    record = StepRecord()
    for accel, yaw in ((0.5, 0.0), (0.8, 0.1), (1.0, 0.1)):
        record.add({"collision": False, "at_fault": False, "offroad": False, "speed": 10.0, "acceleration": accel,
                    "yaw_rate": yaw})  # fmt: skip
    smooth = comfort_figures(record)
    assert smooth["comfortable"] and smooth["max_abs_jerk"] == pytest.approx(3.0)  # (0.8 - 0.5) / 0.1
    assert smooth["max_abs_lateral_acceleration"] == pytest.approx(1.0)
    record.add({"collision": False, "at_fault": False, "offroad": False, "speed": 10.0, "acceleration": -6.0,
                "yaw_rate": 0.0})  # fmt: skip
    harsh = comfort_figures(record)
    assert not harsh["comfortable"] and harsh["min_acceleration"] == -6.0 < COMFORT_BOUNDS["min_acceleration"]


def test_a_run_at_a_junctions_mouth_is_a_run_where_wosacs_nearest_segment_misses_it(real_data_dir):
    """637f's 1580 as simulated in a red-light case: over lane 448's red stop point, heading south, at step 26."""
    from langtraj.metrics.traffic_lights import SignalLanes, red_light_violations
    from langtraj.scenario.io import read_scenario

    scenario = read_scenario(real_data_dir / "motion_data_one_scenario.tfrecord", 0)
    lights = scenario.traffic_lights
    before, now = np.array([[-7791.885, -6686.3657]]), np.array([[-7791.825, -6686.8413]])
    states, seen = lights.held_at(26)
    stop = seen & np.isin(states, [int(TrafficLightState.STOP), int(TrafficLightState.ARROW_STOP)])
    assert stop[list(lights.lane_ids).index(448)]
    episode = EpisodeLights(scenario)
    assert episode.runs(before, now, np.array([-np.pi / 2]), 26)[0]
    assert not episode.runs(before, now, np.array([0.0]), 26)[0]  # heading across the lane: no pass
    green = replace(lights, states=np.full_like(lights.states, int(TrafficLightState.GO)))
    assert not EpisodeLights(replace(scenario, traffic_lights=green)).runs(before, now, np.array([-np.pi / 2]), 26)[0]
    signals = replace(SignalLanes.from_scenario(scenario), signal_is_stop=np.stack([stop, stop]))
    x, y = np.concatenate([before[:, 0], now[:, 0]]), np.concatenate([before[:, 1], now[:, 1]])
    assert not red_light_violations(signals, x, y, np.ones(2, bool))[1]  # the challenge's rule misses it
