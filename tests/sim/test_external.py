"""External agents (an ego under test): written from outside step by step, seen by the model, forecast for its
guidance and selection, never moved by a policy; and the stepped simulation that drives them."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from scenario_builders import make_scenario

from langtraj.sim.config import SimConfig, SimRequest
from langtraj.sim.engine import simulate
from langtraj.sim.external import forecast, pin_external
from langtraj.sim.setup import build_policy
from langtraj.sim.stepping import SteppedSimulation
from langtraj.sim.world import SimWorld


def test_forecast_holds_speed_or_brakes_to_a_stop():
    current = torch.tensor([[0.0, 0.0, 0.0, 10.0]])
    steady = forecast(current, 20)
    assert torch.allclose(steady[0, :, 0], torch.arange(1, 21) * 1.0)
    braking = forecast(current, 40, torch.tensor([-5.0]))
    assert braking[0, -1, 3] == 0 and braking[0, -1, 0] == pytest.approx(10.0, abs=1e-4)  # v^2 / 2a


def test_pin_replaces_only_the_external_slots():
    states = torch.randn(3, 2, 4, 5, 4)  # [M, R, A, T, 4]
    current = torch.zeros(2, 4, 4)
    current[:, 1] = torch.tensor([1.0, 2.0, 0.0, 3.0])
    pinned = pin_external(states, current, [1])
    assert torch.equal(pinned[:, :, [0, 2, 3]], states[:, :, [0, 2, 3]])
    assert torch.allclose(pinned[:, :, 1, :, 0], 1.0 + 0.3 * torch.arange(1, 6).float())


def test_a_world_moves_its_external_agent_only_by_place():
    scenario = make_scenario(4)
    world = SimWorld(scenario, np.array([0, 1, 3]), 1, external=np.array([0]))
    before = world.states[0, 0, 11].copy()
    world.execute(10, np.full((1, 3, 1, 4), 5.0))
    assert np.array_equal(world.states[0, 0, 11], before)  # the policy's column for the ego is ignored
    assert world.states[0, 1, 11, 0] == 5.0
    world.place(10, np.array([[[7.0, 8.0, 0.0, 2.0]]]))
    assert world.states[0, 0, 11, :2].tolist() == [7.0, 8.0]
    assert not world.scenario_at(0, 11).agents.valid[0, 12:].any()  # its future is not known yet
    with pytest.raises(ValueError, match="non-finite"):
        world.place(11, np.array([[[np.nan, 0.0, 0.0, 0.0]]]))


def test_stepping_without_external_agents_is_the_engine():
    scenario = make_scenario(4)
    request = SimRequest(policy="constant_velocity")
    engine = simulate(scenario, build_policy(scenario, request)[0], SimConfig(rollouts=1, seed=3))
    stepped = SteppedSimulation(
        scenario, build_policy(scenario, request)[0], np.zeros(0, np.int64), SimConfig(rollouts=1, seed=3)
    )
    while not stepped.done:
        stepped.advance(np.zeros((1, 0, 4)))
    assert np.array_equal(stepped.world.states, engine.world.states)
