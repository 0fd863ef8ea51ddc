"""A closed-loop simulation advanced one step (0.1 s) at a time, for agents moved from outside (an ego under test,
docs/testing.md): the policy replans its agents every `replan_s` from what every agent, the external ones
included, actually did; between replans they execute the plan, as in `engine.simulate`."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from langtraj.errors import InputError
from langtraj.rollouts.agents import sim_agent_indices
from langtraj.scenario.model import Scenario
from langtraj.sim.config import SimConfig
from langtraj.sim.policies import Policy
from langtraj.sim.world import SimWorld


class SteppedSimulation:
    """`policy` drives the scene's sim agents but `external` (scenario rows), whose next poses each `advance` is
    given. A model policy that drives the external agents too sees them as context; it never moves them. `routes`:
    track id -> the route [P, 2] (world frame) an external agent drives (an ego's mission, `roads.mission`), which
    behaviours staged toward it read as its way (`SimWorld.routes`)."""

    def __init__(
        self,
        scenario: Scenario,
        policy: Policy,
        external: np.ndarray,
        config: SimConfig | None = None,
        routes: Mapping[int, np.ndarray] | None = None,
    ):
        self.config = config = SimConfig(rollouts=1) if config is None else config
        sim_agents = sim_agent_indices(scenario)
        external = np.asarray(external, np.int64)
        if not set(external.tolist()) <= set(sim_agents.tolist()):
            raise InputError("an external agent must be valid at the scene's current step", where="ego")
        driven = policy.drives(scenario, sim_agents)
        self.policy = policy
        self.world = SimWorld(
            scenario, driven, config.rollouts, undriven=policy.undriven, external=external, routes=routes
        )
        self.state: Any = policy.reset(self.world, config.seed)
        self.step = self.world.start
        self._plan: np.ndarray | None = None
        self._planned_at = self.step

    @property
    def done(self) -> bool:
        """Whether the 8 s are simulated."""
        return self.step >= self.world.end

    def advance(self, external_poses: np.ndarray) -> None:
        """Move every agent one step: the external ones to `external_poses` [R, A_e, 4] (world x, y, heading,
        speed), the others by the policy's plan, replanned first when a replan is due."""
        if self.done:
            raise RuntimeError("the simulation is over (8 s simulated)")
        every = self.config.replan_steps
        if self._plan is None or self.step - self._planned_at >= every:
            horizon = min(every, self.world.end - self.step)
            self._plan = self.policy.plan(self.world, self.state, self.step, horizon)
            self._planned_at = self.step
        k = self.step - self._planned_at
        poses = self.policy.act(self.world, self.state, self.step, self._plan[:, :, k])
        self.world.execute(self.step, poses[:, :, None])
        self.world.place(self.step, external_poses)
        self.step += 1

    def report(self) -> dict[str, Any]:
        """The policy's figures of the simulation so far (`Policy.report`)."""
        return self.policy.report(self.world, self.state)
