"""No simulated agent reads its logged future (the WOSAC rule): every registered policy gives the same
rollouts when the log's future is replaced by anything else, unless log-following is asked for, which
the rollouts then flag (docs/simulation.md, 'Driven agents')."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scenario_builders import make_scenario

from langtraj.scenario.types import StateField
from langtraj.sim import SimConfig, simulate
from langtraj.sim.config import SimRequest
from langtraj.sim.policies import POLICIES
from langtraj.sim.setup import build_policy

REQUESTS = {"guidance_baseline": {"prompts": ("@7 yields to @17",)}}


def tampered(scenario, seed: int = 3):
    """The scenario with every agent's logged future moved and turned at random (validity unchanged)."""
    rng = np.random.default_rng(seed)
    states = scenario.agents.states.copy()
    later = slice(scenario.current_index + 1, None)
    shape = states[:, later, 0].shape
    states[:, later, StateField.X] += rng.uniform(-8, 8, shape).astype(np.float32)
    states[:, later, StateField.Y] += rng.uniform(-8, 8, shape).astype(np.float32)
    states[:, later, StateField.HEADING] += rng.uniform(-1, 1, shape).astype(np.float32)
    states[:, later, StateField.VX : StateField.VY + 1] *= 3.0
    return replace(scenario, agents=replace(scenario.agents, states=states))


def rollouts_of(scenario, request):
    policy, _ = build_policy(scenario, request)
    return simulate(scenario, policy, SimConfig(rollouts=2, replan_s=2.0, seed=1)).rollouts


@pytest.mark.parametrize("name", POLICIES.names())
def test_no_policy_reads_the_logged_future(name, tiny_run):
    checkpoint, _ = tiny_run
    scenario = make_scenario(5)
    request = SimRequest(policy=name, checkpoint=checkpoint, candidates=2, steps=2, **REQUESTS.get(name, {}))
    honest, swapped = rollouts_of(scenario, request), rollouts_of(tampered(scenario), request)
    if name == "log_replay":  # the labelled baseline that replays the log: it must differ, and say so
        assert honest.reads_future_log and not np.allclose(honest.x, swapped.x)
        return
    assert not honest.reads_future_log
    for field in ("x", "y", "heading"):
        np.testing.assert_array_equal(getattr(honest, field), getattr(swapped, field), err_msg=field)


def test_log_following_undriven_agents_read_the_future_and_are_flagged(tiny_run):
    checkpoint, _ = tiny_run
    scenario = make_scenario(5)
    request = SimRequest(checkpoint=checkpoint, candidates=2, steps=2, max_driven=2, undriven="log")
    honest, swapped = rollouts_of(scenario, request), rollouts_of(tampered(scenario), request)
    assert honest.log_following_ids.tolist() == [37, 47]
    assert not np.allclose(honest.x[:, 2:], swapped.x[:, 2:])  # the tamper test can fail


def test_capped_model_leaves_the_others_to_constant_velocity(tiny_run):
    checkpoint, _ = tiny_run
    scenario = make_scenario(5)
    request = SimRequest(checkpoint=checkpoint, candidates=2, steps=2, max_driven=2)
    honest, swapped = rollouts_of(scenario, request), rollouts_of(tampered(scenario), request)
    np.testing.assert_array_equal(honest.x, swapped.x)
    assert not honest.reads_future_log
