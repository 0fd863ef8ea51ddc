"""Red-light violations on hand-built lanes and signals, and their likelihood through `evaluate_scenario`."""

from __future__ import annotations

import math

import numpy as np
import pytest

from langtraj.metrics.traffic_lights import SignalLanes, red_light_violations
from langtraj.metrics.wosac import evaluate_scenario
from langtraj.rollouts import Rollouts
from langtraj.scenario import (
    FUTURE_STEPS,
    Agents,
    AgentType,
    MapFeature,
    MapFeatureType,
    RoadMap,
    Scenario,
    TrafficLights,
    TrafficLightState,
)

RED, GREEN = TrafficLightState.STOP, TrafficLightState.GO
STOP_X = 38.0
LANE_POINTS = np.stack([np.linspace(-50, 150, 41), np.zeros(41), np.zeros(41)], axis=1)  # every 5 m along +x


def _scenario(
    states: np.ndarray | None,
    *,
    num_steps: int = 20,
    signal_lanes: tuple[int, ...] = (100, 101),
    lane_type: MapFeatureType = MapFeatureType.LANE_SURFACE_STREET,
    agent_x: np.ndarray | None = None,
    agent_y: tuple[float, ...] = (0.0,),
    tracks_to_predict: tuple[int, ...] = (),
) -> Scenario:
    """Lanes 100 (y = 0) and 101 (y = 3.5) along +x with stop points at x = 38; `states` [T, signals]."""
    num_agents = len(agent_y)
    xs = np.zeros((num_agents, num_steps)) if agent_x is None else agent_x
    agent_states = np.zeros((num_agents, num_steps, 9), np.float32)
    agent_states[..., 0] = xs
    agent_states[..., 1] = np.array(agent_y)[:, None]
    agent_states[..., 2] = 0.75
    agent_states[..., 6:9] = (4.5, 2.0, 1.5)
    features = [
        MapFeature(100, lane_type, LANE_POINTS),
        MapFeature(101, lane_type, LANE_POINTS + [0, 3.5, 0]),
        MapFeature(300, MapFeatureType.ROAD_EDGE_BOUNDARY, LANE_POINTS + [0, -2.0, 0]),  # road on the left
        MapFeature(301, MapFeatureType.ROAD_EDGE_BOUNDARY, LANE_POINTS[::-1] + [0, 5.5, 0]),
    ]
    if states is None:
        lights = TrafficLights.empty(num_steps)
    else:
        stops = [[STOP_X, 0.0 if lane == 100 else 3.5, 0.0] for lane in signal_lanes]
        lights = TrafficLights(list(signal_lanes), states, np.ones(states.shape, bool), stops)
    return Scenario(
        scenario_id="lights",
        timestamps=np.arange(num_steps) * 0.1,
        current_index=min(10, num_steps - 1),
        sdc_index=0,
        agents=Agents(
            ids=np.arange(num_agents) + 1,
            types=np.full(num_agents, AgentType.VEHICLE, np.int8),
            states=agent_states,
            valid=np.ones((num_agents, num_steps), bool),
            tracks_to_predict=list(tracks_to_predict),
        ),
        road_map=RoadMap(tuple(features)),
        traffic_lights=lights,
    )


def _states(num_steps: int = 20, *columns) -> np.ndarray:
    return np.stack([np.full(num_steps, int(c), np.int8) if np.isscalar(c) else c for c in columns], axis=1)


def _signals(states: np.ndarray, **kwargs) -> SignalLanes:
    signals = SignalLanes.from_scenario(_scenario(states, num_steps=len(states), **kwargs))
    assert signals is not None
    return signals


# The car's centre passes x = 38 between step 7 (37.5) and step 8 (38.5).
DRIVE_X = 30.5 + np.arange(20.0)


def test_running_the_red_violates_at_the_crossing_step() -> None:
    signals = _signals(_states(20, RED, RED))
    got = red_light_violations(signals, DRIVE_X, np.zeros(20), np.ones(20, bool))
    assert np.flatnonzero(got).tolist() == [8]
    # Exact lane matching gives the same here.
    exact = red_light_violations(signals, DRIVE_X, np.zeros(20), np.ones(20, bool), exact_lane_match=True)
    assert np.flatnonzero(exact).tolist() == [8]
    # On lane 101 with its own red signal.
    assert np.flatnonzero(red_light_violations(signals, DRIVE_X, np.full(20, 3.5), np.ones(20, bool))).tolist() == [8]


def test_green_or_stopping_short_is_no_violation() -> None:
    valid = np.ones(20, bool)
    assert not red_light_violations(_signals(_states(20, GREEN, GREEN)), DRIVE_X, np.zeros(20), valid).any()
    red = _signals(_states(20, RED, RED))
    stops_short = np.minimum(DRIVE_X, 37.0)
    assert not red_light_violations(red, stops_short, np.zeros(20), valid).any()
    # Driving away from the line (it starts past it) crosses nothing either.
    assert not red_light_violations(red, DRIVE_X[::-1], np.zeros(20), valid).any()


def test_only_the_state_at_the_crossing_step_counts() -> None:
    valid, y = np.ones(20, bool), np.zeros(20)
    red_at_8 = np.where(np.arange(20) == 8, int(RED), int(GREEN)).astype(np.int8)
    red_at_7 = np.where(np.arange(20) == 7, int(RED), int(GREEN)).astype(np.int8)
    got = red_light_violations(_signals(_states(20, red_at_8, GREEN)), DRIVE_X, y, valid)
    assert np.flatnonzero(got).tolist() == [8]
    assert not red_light_violations(_signals(_states(20, red_at_7, GREEN)), DRIVE_X, y, valid).any()


@pytest.mark.parametrize(
    ("state", "violates"),
    [
        (TrafficLightState.ARROW_STOP, True),
        (TrafficLightState.FLASHING_STOP, False),  # as WOSAC: only STOP and ARROW_STOP
        (TrafficLightState.CAUTION, False),
        (TrafficLightState.UNKNOWN, False),
    ],
)
def test_stop_states(state: TrafficLightState, violates: bool) -> None:
    got = red_light_violations(_signals(_states(20, state, state)), DRIVE_X, np.zeros(20), np.ones(20, bool))
    assert got.any() == violates


def test_car_on_another_lane_does_not_violate() -> None:
    # Only lane 100 is signalled; a car on lane 101 passes the same x.
    signals = _signals(_states(20, RED), signal_lanes=(100,))
    assert not red_light_violations(signals, DRIVE_X, np.full(20, 3.5), np.ones(20, bool)).any()
    assert red_light_violations(signals, DRIVE_X, np.zeros(20), np.ones(20, bool)).any()


def test_signal_on_a_lane_missing_from_the_map_is_ignored() -> None:
    signals = _signals(_states(20, RED), signal_lanes=(999,))
    assert not red_light_violations(signals, DRIVE_X, np.zeros(20), np.ones(20, bool)).any()


def test_invalid_step_is_no_violation() -> None:
    valid = np.ones(20, bool)
    valid[8] = False
    assert not red_light_violations(_signals(_states(20, RED, RED)), DRIVE_X, np.zeros(20), valid).any()


def test_batched_tracks() -> None:
    signals = _signals(_states(20, RED, RED))
    x = np.stack([DRIVE_X, np.minimum(DRIVE_X, 37.0), DRIVE_X + 0.2])[None].repeat(2, axis=0)  # [2, 3, 20]
    y = np.zeros_like(x)
    y[1, 0] = 3.5  # lane 101, also red
    got = red_light_violations(signals, x, y, np.ones(x.shape, bool))
    assert got.shape == (2, 3, 20)
    # DRIVE_X + 0.2 is 37.7 at step 7 and 38.7 at step 8.
    assert [np.flatnonzero(row).tolist() for row in got.reshape(6, 20)] == [[8], [], [8], [8], [], [8]]


def test_no_lights_or_no_surface_street_lanes() -> None:
    assert SignalLanes.from_scenario(_scenario(None)) is None
    freeway = _scenario(_states(20, RED, RED), lane_type=MapFeatureType.LANE_FREEWAY)
    assert SignalLanes.from_scenario(freeway) is None
    got = red_light_violations(None, DRIVE_X, np.zeros(20), np.ones(20, bool))
    assert got.shape == (20,) and not got.any()


# ----------------------------------------------------------------------------------------------------------
# End to end: the likelihood and the simulated rate through evaluate_scenario.

NUM_STEPS, CURRENT, NUM_ROLLOUTS = 91, 10, 4


def _log_x() -> np.ndarray:
    """4 m/s until the current step (x = 20.1 -> 24.1), then braking at 1 m/s^2 to a stop at 32.1 (< 38)."""
    x = np.empty(NUM_STEPS)
    t_after = np.clip((np.arange(NUM_STEPS) - CURRENT) * 0.1, 0.0, 4.0)
    x[:] = 24.1 + 4.0 * t_after - 0.5 * t_after**2
    x[: CURRENT + 1] = 20.1 + 0.4 * np.arange(CURRENT + 1)
    return x


def _red_light_scene() -> Scenario:
    x = np.stack([_log_x(), _log_x()])  # the SDC on lane 100, the track to predict beside it on lane 101
    return _scenario(
        _states(NUM_STEPS, RED, RED),
        num_steps=NUM_STEPS,
        agent_x=x,
        agent_y=(0.0, 3.5),
        tracks_to_predict=(1,),
    )


def _rollouts(scene: Scenario, running: list[bool]) -> Rollouts:
    """Rollout r keeps 4 m/s through the line (x = 37.7 at future step 34, 38.1 at 35) when running[r],
    else replays the log."""
    log = scene.agents.states[:, CURRENT + 1 :, 0].astype(np.float64)
    through = 24.1 + 0.4 * np.arange(1, FUTURE_STEPS + 1)
    x = np.stack([np.broadcast_to(through, log.shape) if run else log for run in running])
    y = np.broadcast_to(np.array([0.0, 3.5])[None, :, None], x.shape)
    zeros = np.zeros(x.shape)
    return Rollouts(scene.agents.ids, x, y, zeros + 0.75, zeros, scenario_id=scene.scenario_id)


def test_evaluate_scenario_red_light_runners() -> None:
    scene = _red_light_scene()
    metrics = evaluate_scenario(scene, _rollouts(scene, [True] * NUM_ROLLOUTS))
    # Both evaluated agents: the log never violates, every rollout does -> p = 0.001 / (4 + 0.002) each.
    assert metrics.simulated_traffic_light_violation_rate == 1.0
    assert metrics.traffic_light_violation_likelihood == pytest.approx(0.001 / 4.002, rel=1e-9)
    assert metrics.traffic_light_violation_likelihood < 1e-3


def test_evaluate_scenario_log_replay_and_mixed() -> None:
    scene = _red_light_scene()
    replay = evaluate_scenario(scene, _rollouts(scene, [False] * NUM_ROLLOUTS))
    assert replay.simulated_traffic_light_violation_rate == 0.0
    assert replay.traffic_light_violation_likelihood == pytest.approx(4.001 / 4.002, rel=1e-9)
    mixed = evaluate_scenario(scene, _rollouts(scene, [True, False, True, False]))
    assert mixed.simulated_traffic_light_violation_rate == 0.5
    assert mixed.traffic_light_violation_likelihood == pytest.approx(2.001 / 4.002, rel=1e-9)
    assert math.isfinite(mixed.metametric)
