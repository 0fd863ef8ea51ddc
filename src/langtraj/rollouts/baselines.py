"""Reference rollout generators (constant velocity, log replay, stationary) to calibrate the metrics against.

Each baseline is registered in `BASELINES` under its `name`; `generate_baseline` builds one by name with
its options. The rules are those that produced the official WOSAC reference figures (docs/metrics.md):
the reference rollouts are reproduced exactly when the
baselines are fed the float64 positions of the WOMD proto (`RolloutBaseline.poses`), and to within the
float32 rounding of the input when fed a `Scenario` (whose states are float32).

Extension rule shared by all baselines ("constant velocity at step s"): the agent keeps, per 0.1 s
step, the displacement (x, y, z) from step s-1 to step s when step s-1 is valid, or else its step-s
velocity (vx, vy) times 0.1 s with no vertical motion; the heading stays at its step-s value. This is
the project's one constant-velocity rule: the simulator's constant-velocity policy and the open-loop
constant-velocity reference use it too.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from langtraj.angles import wrap_angle
from langtraj.errors import InputError
from langtraj.registry import Registry
from langtraj.rollouts.agents import sim_agent_indices
from langtraj.rollouts.container import WOSAC_ROLLOUTS, Rollouts
from langtraj.scenario.model import FUTURE_STEPS, STEP_SECONDS, Scenario
from langtraj.scenario.types import StateField

_POSE = [StateField.X, StateField.Y, StateField.Z, StateField.HEADING]
_XYZ = slice(StateField.X, StateField.Z + 1)
_VXY = slice(StateField.VX, StateField.VY + 1)


def _constant_velocity_step(states: np.ndarray, valid: np.ndarray, index: np.ndarray) -> np.ndarray:
    """Per-step displacement [A, 3] of each agent at its step `index[a]` (the module's extension rule)."""
    agents = np.arange(len(index))
    prev = np.maximum(index - 1, 0)
    prev_valid = (index >= 1) & valid[agents, prev]
    moved = states[agents, index, _XYZ] - states[agents, prev, _XYZ]
    planar = np.zeros_like(moved)
    planar[:, :2] = states[agents, index, _VXY] * STEP_SECONDS
    return np.where(prev_valid[:, None], moved, planar)


def _extend(states: np.ndarray, valid: np.ndarray, index: np.ndarray, steps: np.ndarray) -> np.ndarray:
    """Poses [A, len(steps), 4] at absolute `steps` by constant velocity from each agent's step `index[a]`."""
    agents = np.arange(len(index))
    origin = states[agents, index][:, _POSE]  # [A, 4]
    ahead = (steps[None, :] - index[:, None]).astype(states.dtype)  # [A, S]
    out = np.repeat(origin[:, None, :], len(steps), axis=1)
    out[..., :3] += ahead[..., None] * _constant_velocity_step(states, valid, index)[:, None, :]
    return out


def _check_tracks(states: np.ndarray, valid: np.ndarray, current_index: int) -> None:
    if states.ndim != 3 or states.shape[-1] <= StateField.VY or valid.shape != states.shape[:2]:
        raise InputError(
            f"expected states [A, T, >={StateField.VY + 1}] and valid [A, T], got {states.shape}, {valid.shape}"
        )
    if not 0 <= current_index < states.shape[1]:
        raise InputError(f"current index {current_index} outside [0, {states.shape[1]})")
    if not valid[:, current_index].all():
        raise InputError("every track must be valid at the current step (only sim agents are simulated)")


class RolloutBaseline(ABC):
    """A rollout generator that needs no model: `generate` gives R joint rollouts of a scene's sim agents."""

    name: ClassVar[str]
    reads_future_log: ClassVar[bool] = False  # log replay: its rollouts are flagged (`Rollouts.log_following_ids`)

    @abstractmethod
    def poses(self, states: np.ndarray, valid: np.ndarray, current_index: int, num_steps: int = FUTURE_STEPS):
        """Deterministic future poses [A, num_steps, 4] (x, y, z, heading) of tracks valid at `current_index`.

        `states` [A, T, >=6] holds `StateField` columns and `valid` [A, T] their validity; computed in
        float64 (pass float64 logs, e.g. the WOMD proto's, to keep sub-millimetre motion).
        """

    def generate(self, scenario: Scenario, num_rollouts: int = WOSAC_ROLLOUTS, *, seed: int = 0) -> Rollouts:
        """`num_rollouts` joint rollouts of the scene's sim agents (in track order) over `FUTURE_STEPS` steps."""
        if num_rollouts < 1:
            raise InputError(f"num_rollouts must be at least 1, got {num_rollouts}", where=f"baseline {self.name}")
        agents = sim_agent_indices(scenario)
        states = scenario.agents.states[agents].astype(np.float64)
        future = self.poses(states, scenario.agents.valid[agents], scenario.current_index, FUTURE_STEPS)
        future = np.broadcast_to(future, (num_rollouts, *future.shape))
        x, y, z, heading = self._perturb(future, seed)
        return Rollouts(
            object_id=scenario.agents.ids[agents],
            x=x.astype(np.float32),
            y=y.astype(np.float32),
            z=z.astype(np.float32),
            heading=wrap_angle(heading).astype(np.float32),
            scenario_id=scenario.scenario_id,
            log_following_ids=scenario.agents.ids[agents] if self.reads_future_log else None,
        )

    def _perturb(self, future: np.ndarray, seed: int) -> tuple[np.ndarray, ...]:
        """x, y, z, heading [R, A, T] from the (broadcast) poses [R, A, T, 4]; no noise by default."""
        return tuple(future[..., i] for i in range(4))


BASELINES: Registry[RolloutBaseline] = Registry("rollout baseline")
"""The rollout baselines by name."""


@BASELINES.register
@dataclass(frozen=True)
class ConstantVelocity(RolloutBaseline):
    """Each sim agent keeps its current displacement per step (see the module's extension rule)."""

    name: ClassVar[str] = "constant_velocity"

    def poses(self, states, valid, current_index, num_steps=FUTURE_STEPS):
        states, valid = np.asarray(states, np.float64), np.asarray(valid, bool)
        _check_tracks(states, valid, current_index)
        index = np.full(len(states), current_index, np.int64)
        return _extend(states, valid, index, current_index + 1 + np.arange(num_steps))

    def model_states(self, states, valid, current_index, num_steps=FUTURE_STEPS) -> np.ndarray:
        """The poses as the model's states [A, num_steps, 4] (x, y, heading, speed), float64; the speed is the
        first step's displacement from the current position over `STEP_SECONDS`, held (constant velocity)."""
        poses = self.poses(states, valid, current_index, num_steps)
        current_xy = np.asarray(states, np.float64)[:, current_index, StateField.X : StateField.Y + 1]
        speed = np.linalg.norm(poses[:, :1, :2] - current_xy[:, None], axis=-1, keepdims=True) / STEP_SECONDS
        return np.concatenate([poses[..., :2], poses[..., 3:], np.broadcast_to(speed, poses[..., :1].shape)], -1)


@BASELINES.register
@dataclass(frozen=True)
class Stationary(RolloutBaseline):
    """Every sim agent frozen at its current-step pose."""

    name: ClassVar[str] = "stationary"

    def poses(self, states, valid, current_index, num_steps=FUTURE_STEPS):
        states, valid = np.asarray(states, np.float64), np.asarray(valid, bool)
        _check_tracks(states, valid, current_index)
        return np.repeat(states[:, current_index, None][..., _POSE], num_steps, axis=1)


@BASELINES.register
@dataclass(frozen=True)
class LogReplay(RolloutBaseline):
    """The logged future, gaps filled, optionally with Gaussian noise.

    Invalid logged steps between valid ones are linearly interpolated (heading unwrapped first, wrapped
    to (-pi, pi] after). After the last valid step L (and past the end of a short log, e.g. a window)
    the agent moves by constant velocity at L (the module's extension rule: displacement from L-1 when
    L-1 is valid, else the step-L velocity with no vertical motion; heading held); an agent with no
    valid future thus continues as `constant_velocity`.

    noise_std: std (m) of independent Gaussian noise on x and y per rollout, agent and step; the heading
        gets noise_std / 10 rad. Drawn from `np.random.default_rng(seed)`; 0 gives identical rollouts.
    """

    name: ClassVar[str] = "log_replay"
    reads_future_log: ClassVar[bool] = True
    noise_std: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.noise_std) and self.noise_std >= 0):
            raise InputError(f"must be a finite value >= 0, got {self.noise_std}", where="log_replay noise_std")

    def poses(self, states, valid, current_index, num_steps=FUTURE_STEPS):
        states, valid = np.asarray(states, np.float64), np.asarray(valid, bool)
        _check_tracks(states, valid, current_index)
        steps = current_index + 1 + np.arange(num_steps)
        future = valid.copy()
        future[:, :current_index] = False  # interpolation uses the current step and the logged future only
        last = np.array([np.flatnonzero(row)[-1] for row in future], np.int64).reshape(len(states))
        out = _extend(states, valid, last, steps)
        for a, end in enumerate(last):
            inside = steps <= end
            if not inside.any():
                continue
            known = np.flatnonzero(future[a])
            pose = states[a, known][:, _POSE]
            pose[:, 3] = np.unwrap(pose[:, 3])
            for col in range(4):
                out[a, inside, col] = np.interp(steps[inside], known, pose[:, col])
        out[..., 3] = wrap_angle(out[..., 3])
        return out

    def _perturb(self, future: np.ndarray, seed: int) -> tuple[np.ndarray, ...]:
        x, y, z, heading = (future[..., i] for i in range(4))
        if self.noise_std == 0:
            return x, y, z, heading
        rng = np.random.default_rng(seed)
        shape = future.shape[:3]
        x = x + rng.normal(0.0, self.noise_std, shape)
        y = y + rng.normal(0.0, self.noise_std, shape)
        heading = heading + rng.normal(0.0, self.noise_std / 10, shape)
        return x, y, z, heading


def generate_baseline(
    name: str, scenario: Scenario, num_rollouts: int = WOSAC_ROLLOUTS, *, seed: int = 0, **options
) -> Rollouts:
    """Rollouts of `scenario` by the baseline called `name`, built with `options` (its dataclass fields).

    An unknown name or option raises InputError (the former lists the known baselines).
    """
    baseline = BASELINES.create(name)
    if options:
        try:
            baseline = type(baseline)(**options)
        except TypeError as exc:
            raise InputError(f"bad options {sorted(options)}: {exc}", where=f"baseline {name}") from None
    return baseline.generate(scenario, num_rollouts, seed=seed)
