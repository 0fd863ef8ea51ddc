"""The closed-loop rollout engine: replan every `replan_s`, execute, shift the history, repeat to 8 s.

At each replan step the policy plans every rollout's driven agents from that rollout's own simulated
past; the world executes the first `replan_s` seconds of the plan at 10 Hz (each step as the policy's `act`
makes it: the plan, or a scripted agent's correction from the scene then) and the next replan starts from
there (paper 'Implementation Details': 1 Hz replanning over an 8 s simulation). All R rollouts advance together,
so a policy can batch them through its model.

See docs/simulation.md.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from langtraj.errors import InputError
from langtraj.rollouts.agents import sim_agent_indices
from langtraj.rollouts.container import Rollouts
from langtraj.scenario.model import FUTURE_STEPS, Scenario
from langtraj.sim.config import SimConfig
from langtraj.sim.policies import Policy
from langtraj.sim.world import SimWorld


def replan_schedule(start: int, every: int, total: int = FUTURE_STEPS) -> list[tuple[int, int]]:
    """(replan step, steps executed) pairs covering steps start+1 ... start+total: [(10, 10), (20, 10), ...]."""
    if every < 1:
        raise ValueError(f"replanning interval must be at least one step, got {every}")
    return [(t, min(every, start + total - t)) for t in range(start, start + total, every)]


@dataclass
class SimResult:
    """What a simulation produced: the rollouts, which tracks the policy drove, and where time went."""

    rollouts: Rollouts
    world: SimWorld  # the simulated tracks (`world.scenario`: the scene extended to 8 s of future)
    driven_ids: np.ndarray  # int64 [A_d]: track ids the policy drove (the others moved as `world.undriven`)
    schedule: list[tuple[int, int]]
    seconds: float
    plan_seconds: list[float] = field(default_factory=list)
    report: dict[str, Any] = field(default_factory=dict)  # the policy's figures (`Policy.report`), JSON-ready

    def scenario(self, rollout: int = 0) -> Scenario:
        """The scene as rollout `rollout` played it (for rendering): every simulated step valid."""
        return self.world.played(rollout)


def simulate(scenario: Scenario, policy: Policy, config: SimConfig | None = None) -> SimResult:
    """R closed-loop rollouts of the scene's sim agents over the 8 s after its current step."""
    config = SimConfig() if config is None else config
    sim_agents = sim_agent_indices(scenario)
    if not len(sim_agents):
        raise InputError(f"scenario {scenario.scenario_id} has no agent valid at its current step", where="agents")
    begin = time.perf_counter()
    driven = policy.drives(scenario, sim_agents)
    world = SimWorld(scenario, driven, config.rollouts, undriven=policy.undriven)
    state = policy.reset(world, config.seed)
    schedule = replan_schedule(world.start, config.replan_steps)
    plan_seconds = []
    for step, count in schedule:
        tick = time.perf_counter()
        plan = policy.plan(world, state, step, count)
        plan_seconds.append(time.perf_counter() - tick)
        for k in range(count):  # step by step: a policy may drive some agents at 10 Hz (`Policy.act`)
            world.execute(step + k, policy.act(world, state, step + k, plan[:, :, k])[:, :, None])
    return SimResult(
        rollouts=world.rollouts(),
        world=world,
        driven_ids=scenario.agents.ids[driven].astype(np.int64),
        schedule=schedule,
        seconds=time.perf_counter() - begin,
        plan_seconds=plan_seconds,
        report=policy.report(world, state),
    )
