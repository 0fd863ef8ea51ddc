"""Traffic flow against the log (`metrics.flow`) on constructed scenes with known answers."""

from __future__ import annotations

import math

import numpy as np

from langtraj.metrics.flow import traffic_flow
from langtraj.scenario import AgentType
from tests.metrics.test_controllability import C, log_rollouts, scene, track


def _flowing():
    """Car 101 at 10 m/s, car 102 parked, pedestrian 103 at 1.5 m/s, car 104 at 5 m/s that stops in its log at
    future step 40."""
    stopping = track((0, 20), (0.5, 0))
    stopping[C + 41 :, :2] = stopping[C + 40, :2]
    stopping[C + 41 :, 4:6] = 0.0
    tracks = [track((0, 0), (1, 0)), track((0, 10), (0, 0)), track((0, 30), (0.15, 0)), stopping]
    types = [AgentType.VEHICLE, AgentType.VEHICLE, AgentType.PEDESTRIAN, AgentType.VEHICLE]
    return scene(tracks, types=types)


def test_the_log_flows_as_the_log() -> None:
    """Replaying the log: the ratio is 1 and the stopped shares agree; only the two moving vehicles count."""
    sc = _flowing()
    flow = traffic_flow(sc, log_rollouts(sc))
    assert flow.vehicles == 2
    assert math.isclose(flow.speed_ratio, 1.0, rel_tol=1e-5) and math.isclose(flow.median_ratio, 1.0, rel_tol=1e-5)
    assert flow.stopped == flow.stopped_log == 0.5


def test_traffic_at_half_speed_and_frozen() -> None:
    """Car 101 driven at half its speed in one rollout and standing in the other: pooled ratio over both vehicles'
    distances; the standing one ends stopped where its log does not."""
    sc = _flowing()
    rollouts = log_rollouts(sc)
    start = sc.agents.states[0, C, 0]
    rollouts.x[0, 0] = start + 0.5 * np.arange(1, 81)
    rollouts.x[1, 0] = start
    flow = traffic_flow(sc, rollouts)
    car, stopper = 80.0, 20.0  # logged metres of 101 and 104
    assert math.isclose(flow.speed_ratio, (0.5 * (40.0 + 0.0) + stopper) / (car + stopper), rel_tol=1e-5)
    assert math.isclose(flow.median_ratio, (0.25 + 1.0) / 2, rel_tol=1e-5)
    assert flow.stopped == 0.75 and flow.stopped_log == 0.5


def test_no_moving_vehicle_gives_nan() -> None:
    sc = scene([track((0, 0), (0, 0))])
    flow = traffic_flow(sc, log_rollouts(sc))
    assert flow.vehicles == 0 and math.isnan(flow.speed_ratio) and math.isnan(flow.stopped)
