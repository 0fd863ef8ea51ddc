"""The closed-loop rollout engine: replan every `replan_s`, execute, shift the history, repeat to 8 s.

At each replan step the policy plans every rollout's driven agents from that rollout's own simulated
past; the world executes the first `replan_s` seconds of the plan at 10 Hz and the next replan starts
from there (paper 'Implementation Details': 1 Hz replanning over an 8 s simulation). All R rollouts
advance together, so a policy can batch them through its model.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from langtraj.errors import InputError
from langtraj.rollouts.agents import sim_agent_indices
from langtraj.rollouts.container import FUTURE_STEPS, WOSAC_ROLLOUTS, Rollouts
from langtraj.scenario.model import STEP_SECONDS, Scenario
from langtraj.sim.policies import Policy
from langtraj.sim.world import SimWorld


@dataclass(frozen=True)
class SimConfig:
    """How a scene is simulated: `rollouts` joint rollouts (32 for WOSAC), replanned every `replan_s`
    seconds (a multiple of the 0.1 s step), from random streams fixed by `seed`."""

    rollouts: int = WOSAC_ROLLOUTS
    replan_s: float = 1.0
    seed: int = 0

    def __post_init__(self) -> None:
        if self.rollouts < 1:
            raise InputError(f"rollouts must be at least 1, got {self.rollouts}", where="rollouts")
        steps = self.replan_s / STEP_SECONDS
        if not (steps >= 1 and math.isclose(steps, round(steps), abs_tol=1e-6)) or self.replan_s > 8.0:
            raise InputError(f"replan_s must be a multiple of 0.1 s in [0.1, 8], got {self.replan_s}", where="replan_s")

    @property
    def replan_steps(self) -> int:
        return round(self.replan_s / STEP_SECONDS)


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
    driven_ids: np.ndarray  # int64 [A_d]: track ids the policy drove (everyone else followed the log)
    schedule: list[tuple[int, int]]
    seconds: float
    plan_seconds: list[float] = field(default_factory=list)

    def scenario(self, rollout: int = 0) -> Scenario:
        """The scene as rollout `rollout` played it (for rendering): every simulated step valid."""
        return self.world.played(rollout)


def simulate(scenario: Scenario, policy: Policy, config: SimConfig = SimConfig()) -> SimResult:
    """R closed-loop rollouts of the scene's sim agents over the 8 s after its current step."""
    sim_agents = sim_agent_indices(scenario)
    if not len(sim_agents):
        raise InputError(f"scenario {scenario.scenario_id} has no agent valid at its current step", where="agents")
    begin = time.perf_counter()
    driven = policy.drives(scenario, sim_agents)
    world = SimWorld(scenario, driven, config.rollouts)
    policy.reset(world, config.seed)
    schedule = replan_schedule(world.start, config.replan_steps)
    plan_seconds = []
    for step, count in schedule:
        tick = time.perf_counter()
        plan = policy.plan(world, step, count)
        plan_seconds.append(time.perf_counter() - tick)
        world.execute(step, plan[:, :, :count])
    return SimResult(
        rollouts=world.rollouts(),
        world=world,
        driven_ids=scenario.agents.ids[driven].astype(np.int64),
        schedule=schedule,
        seconds=time.perf_counter() - begin,
        plan_seconds=plan_seconds,
    )
