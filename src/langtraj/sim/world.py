"""The simulated world: every sim agent's track in each of R rollouts, filled in as the simulation runs.

Tracks are kept as a copy of the scenario's agent states per rollout, extended to the full 8 s future,
so a policy sees each rollout's past exactly as a logged scenario (`scenario_at`) and the training
features apply unchanged. Agents that no policy drives follow their log; where the log has no valid
future step they keep their last logged velocity (constant velocity), so every sim agent has a pose at
every step for the rollout file.

See docs/simulation.md.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace

import numpy as np

from langtraj.angles import wrap_angle
from langtraj.errors import InputError
from langtraj.rollouts.agents import sim_agent_indices
from langtraj.rollouts.baselines import generate_baseline
from langtraj.rollouts.container import Rollouts
from langtraj.scenario.model import FUTURE_STEPS, STEP_SECONDS, Agents, Scenario, TrafficLights
from langtraj.scenario.types import StateField
from langtraj.sim.config import UNDRIVEN

POSE_FIELDS = 4
"""Plan states per step: x, y, heading, speed (world frame)."""


def extended_scenario(scenario: Scenario, future_steps: int = FUTURE_STEPS) -> Scenario:
    """The scenario with at least `future_steps` steps after the current one (added steps: invalid
    agents, unknown traffic lights, timestamps continuing at 10 Hz)."""
    need = scenario.current_index + 1 + future_steps
    extra = need - scenario.num_steps
    if extra <= 0:
        return scenario
    agents = scenario.agents
    states = np.concatenate(
        [agents.states, np.zeros((agents.num_agents, extra, agents.states.shape[2]), np.float32)], 1
    )
    valid = np.concatenate([agents.valid, np.zeros((agents.num_agents, extra), bool)], 1)
    last = scenario.timestamps[-1] if scenario.num_steps else 0.0
    timestamps = np.concatenate([scenario.timestamps, last + STEP_SECONDS * np.arange(1, extra + 1)])
    lights = scenario.traffic_lights
    if lights is not None:
        lanes = len(lights.lane_ids)
        lights = TrafficLights(
            lane_ids=lights.lane_ids,
            states=np.concatenate([lights.states, np.zeros((extra, lanes), np.int8)]),
            valid=np.concatenate([lights.valid, np.zeros((extra, lanes), bool)]),
            stop_points=lights.stop_points,
        )
    return replace(
        scenario,
        timestamps=timestamps,
        agents=replace(agents, states=states, valid=valid),
        traffic_lights=lights,
    )


def without_future(scenario: Scenario) -> Scenario:
    """The scenario as a simulation may see it: every agent's steps after the current one invalid and
    zeroed (the log's future is the ground truth a simulation is scored against; WOSAC forbids reading it)."""
    later = slice(scenario.current_index + 1, None)
    states = scenario.agents.states.copy()
    valid = scenario.agents.valid.copy()
    states[:, later] = 0.0
    valid[:, later] = False
    return replace(scenario, agents=replace(scenario.agents, states=states, valid=valid))


class SimWorld:
    """R rollouts of one scene. `driven` (scenario rows, a subset of the sim agents) are written by a
    policy with `execute`; `external` rows (an ego under test, docs/testing.md) are written from outside with
    `place`, step by step, and a policy that drives them too sees them but never moves them; every other sim
    agent moves as `undriven` says (`UNDRIVEN`). Unless it is "log", the world holds no logged future at all:
    no policy can read it. `routes`: track id -> the route [P, 2] (world frame) an external agent drives (an ego's
    mission: the map's lanes its planner is given, never its motion), read as its way by behaviours staged toward it
    (`sim.staging`)."""

    def __init__(
        self,
        scenario: Scenario,
        driven: np.ndarray,
        num_rollouts: int,
        undriven: str = "constant_velocity",
        external: np.ndarray | None = None,
        routes: Mapping[int, np.ndarray] | None = None,
    ):
        if num_rollouts < 1:
            raise ValueError(f"num_rollouts must be at least 1, got {num_rollouts}")
        if undriven not in UNDRIVEN:
            raise InputError(f"must be one of {', '.join(UNDRIVEN)}, got {undriven!r}", where="undriven")
        seen = scenario if undriven == "log" else without_future(scenario)
        self.scenario = extended_scenario(seen)
        self.start = scenario.current_index
        self.end = self.start + FUTURE_STEPS
        self.num_rollouts = num_rollouts
        self.undriven = undriven
        self.sim_agents = sim_agent_indices(scenario)
        sim = set(self.sim_agents.tolist())
        self.driven = np.asarray(driven, np.int64)
        if not set(self.driven.tolist()) <= sim:
            raise ValueError("every driven agent must be a sim agent (valid at the current step)")
        self.external = np.zeros(0, np.int64) if external is None else np.asarray(external, np.int64)
        if not set(self.external.tolist()) <= sim:
            raise ValueError("every external agent must be a sim agent (valid at the current step)")
        self.routes = {int(k): np.asarray(v, np.float64) for k, v in (routes or {}).items()}
        self.others = np.setdiff1d(self.sim_agents, np.union1d(self.driven, self.external))  # nobody moves them
        self._moved = ~np.isin(self.driven, self.external)  # driven columns `execute` writes
        # Undriven agents: the log where `undriven` is "log", and constant velocity wherever no logged
        # state is held (all their future otherwise): the rollout baseline's rule, from the history.
        states = self.scenario.agents.states.copy()
        valid = self.scenario.agents.valid.copy()
        cv = generate_baseline("constant_velocity", seen, 1)
        future = slice(self.start + 1, self.end + 1)
        for col, row in enumerate(self.sim_agents):
            gap = ~valid[row, future]
            if not gap.any():
                continue
            steps = np.arange(self.start + 1, self.end + 1)[gap]
            xy = np.stack([cv.x[0, col], cv.y[0, col]], -1).astype(np.float64)  # [FUTURE_STEPS, 2]
            step_length = np.linalg.norm(np.diff(xy, axis=0, prepend=states[row, self.start, None, :2]), axis=-1)
            poses = np.stack([xy[gap, 0], xy[gap, 1], cv.heading[0, col, gap], step_length[gap] / STEP_SECONDS], -1)
            block = states[row, steps]
            Agents.write_poses(block, poses)
            block[:, StateField.Z] = cv.z[0, col, gap]
            keep = [StateField.LENGTH, StateField.WIDTH, StateField.HEIGHT]
            block[:, keep] = states[row, self.start, keep]
            states[row, steps] = block
            valid[row, steps] = True
        self.states = np.repeat(states[None], num_rollouts, axis=0)  # float32 [R, A_all, T, 9]
        self.valid = np.repeat(valid[None], num_rollouts, axis=0)  # bool [R, A_all, T]

    @property
    def log_following(self) -> np.ndarray:
        """Scenario rows whose simulated future replays the log (empty unless `undriven` is "log")."""
        return self.others if self.undriven == "log" else self.others[:0]

    def scenario_at(self, rollout: int, step: int) -> Scenario:
        """What rollout `rollout` looks like at `step`: its simulated past, `step` as the current index.
        Driven and external agents' steps after `step` are not yet simulated and are marked invalid."""
        states, valid = self.states[rollout], self.valid[rollout].copy()
        valid[self.driven, step + 1 :] = False
        valid[self.external, step + 1 :] = False
        agents = replace(self.scenario.agents, states=states, valid=valid)
        return replace(self.scenario, agents=agents, current_index=step)

    def played(self, rollout: int) -> Scenario:
        """Rollout `rollout` as a scenario: the log up to the start, then the simulated 8 s (tracks that
        are not sim agents, i.e. appear only later in the log, are hidden after the start)."""
        valid = self.valid[rollout].copy()
        others = np.setdiff1d(np.arange(valid.shape[0]), self.sim_agents)
        valid[others, self.start + 1 :] = False
        agents = replace(self.scenario.agents, states=self.states[rollout], valid=valid)
        return replace(self.scenario, agents=agents)

    def current(self, step: int, rows: np.ndarray | None = None) -> np.ndarray:
        """World (x, y, heading, speed) at `step` in every rollout of the driven agents (or `rows`): float64
        [R, A, 4]."""
        s = self.states[:, self.driven if rows is None else rows, step].astype(np.float64)
        speed = np.hypot(s[..., StateField.VX], s[..., StateField.VY])
        return np.stack([s[..., StateField.X], s[..., StateField.Y], s[..., StateField.HEADING], speed], -1)

    def execute(self, step: int, plan: np.ndarray) -> None:
        """Write the driven agents' states for steps step+1 .. step+n: `plan` [R, A_d, n, 4] (x, y, heading,
        speed in the world frame). Height and box size stay at the current step's. External agents' columns of
        the plan are ignored: `place` writes them."""
        r, a, n, _ = plan.shape
        if (r, a) != (self.num_rollouts, len(self.driven)) or step + n > self.end:
            raise ValueError(
                f"plan of shape {plan.shape} does not fit {self.num_rollouts} rollouts, "
                f"{len(self.driven)} driven agents and steps up to {self.end}"
            )
        self._write(step, self.driven[self._moved], plan[:, self._moved], "the policy")

    def place(self, step: int, poses: np.ndarray) -> None:
        """Write the external agents' states at step+1: `poses` [R, A_e, 4] (x, y, heading, speed, world frame)."""
        poses = np.asarray(poses, np.float64)
        if poses.shape != (self.num_rollouts, len(self.external), 4) or step + 1 > self.end:
            raise ValueError(
                f"poses of shape {poses.shape} do not fit {self.num_rollouts} rollouts, {len(self.external)} external "
                f"agents and steps up to {self.end}"
            )
        self._write(step, self.external, poses[:, :, None], "an external agent")

    def _write(self, step: int, rows: np.ndarray, plan: np.ndarray, who: str) -> None:
        """States of `rows` for steps step+1 .. step+n from `plan` [R, len(rows), n, 4]."""
        if not np.isfinite(plan).all():
            raise ValueError(f"{who} produced non-finite states at step {step}")
        cols = np.arange(step + 1, step + 1 + plan.shape[2])
        block = self.states[:, rows][:, :, cols]  # copy [R, A, n, 9]
        Agents.write_poses(block, plan)
        keep = [StateField.Z, StateField.LENGTH, StateField.WIDTH, StateField.HEIGHT]
        block[..., keep] = self.states[:, rows, step][:, :, None, keep]
        self.states[:, rows[:, None], cols[None, :]] = block
        self.valid[:, rows[:, None], cols[None, :]] = True

    def rollouts(self) -> Rollouts:
        """The simulated future of every sim agent (track order) as the metrics' rollout container."""
        future = self.states[:, self.sim_agents, self.start + 1 : self.end + 1]
        return Rollouts(
            object_id=self.scenario.agents.ids[self.sim_agents],
            x=future[..., StateField.X].astype(np.float32),
            y=future[..., StateField.Y].astype(np.float32),
            z=future[..., StateField.Z].astype(np.float32),
            heading=wrap_angle(future[..., StateField.HEADING]).astype(np.float32),
            scenario_id=self.scenario.scenario_id,
            log_following_ids=self.scenario.agents.ids[self.log_following],
        )
