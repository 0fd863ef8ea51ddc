"""Scripted manoeuvres (`interdrive.behaviours.scripts`) in a simulation: the state a script plans from, and its
agents driven at the simulation's rate, 10 Hz, from the scene as it is at each step, between the model's replans,
as a scenario's scripted actor is ticked (OpenSCENARIO, CARLA's ScenarioRunner). At a replan the script's plan is
put in the agent's candidates (`sim.candidates`); between replans `act` re-plans its next step from where every
agent is then, so a cut-in holds its gap on an ego that brakes within a replan, and a trigger ("when @ego is
within 20 m") starts the behaviour at the step it holds, not at the next replan (docs/simulation.md, 'Scripted
manoeuvres').
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from langtraj.angles import wrap_angle
from langtraj.frames import Origin, poses_to_frame, poses_to_world
from langtraj.guidance.steering import Steering
from langtraj.interdrive.behaviours import Script, ScriptState, unicycle_step
from langtraj.model.dynamics import Unicycle
from langtraj.scenario.model import STEP_SECONDS
from langtraj.scenario.types import StateField
from langtraj.sim.external import external_acceleration
from langtraj.sim.prompt_replan import PromptReplans
from langtraj.sim.world import SimWorld


def script_state(
    steering: Steering,
    since: int,
    step: int,
    current: np.ndarray,
    sizes: np.ndarray,
    other_accel: float,
    dynamics: Unicycle,
    count: int,
    per_action: int,
    memory: dict[str, Any],
) -> ScriptState:
    """What the script of `steering` (timed from step `since`) plans from at `step`: the agents' `current` states
    [A, 4] (scene frame: x, y, heading, speed) and `sizes` [A, 2] (length, width), the other agent's acceleration
    (m/s^2), and `count` actions of `per_action` steps of the unicycle `dynamics`. Every agent but the two is its
    traffic; `memory` what the script decided so far (`PromptReplans.memory`)."""
    other = steering.other_slot
    target = steering.target
    rest = np.setdiff1d(np.arange(len(current)), [steering.slot] + ([] if other is None else [other]))
    return ScriptState(
        agent=current[steering.slot],
        other=None if other is None else current[other],
        other_accel=other_accel,
        path=target.path,
        elapsed_s=(step - since) * STEP_SECONDS,
        count=count,
        per_action=per_action,
        dt=dynamics.dt,
        max_yaw_rate=dynamics.max_yaw_rate,
        own_lane=target.own_lane,
        new_lane=target.new_lane,
        size=(float(sizes[steering.slot, 0]), float(sizes[steering.slot, 1])),
        other_size=None if other is None else (float(sizes[other, 0]), float(sizes[other, 1])),
        traffic=np.concatenate([current[rest, :4], sizes[rest, :2]], axis=1),
        memory=memory,
    )


def act(
    world: SimWorld,
    prompt: PromptReplans,
    origin: Origin,
    dynamics: Unicycle,
    step: int,
    poses: np.ndarray,
) -> np.ndarray:
    """The driven agents' poses at step+1 [R, A_d, 4] (world frame) from the `poses` the last replan planned for it:
    the staged behaviours whose trigger holds at `step` started (`PromptReplans.stage`), and each scripted agent
    moved by its script's next action from every agent's state at `step`; where the script leaves an action to the
    model (NaN), the planned one."""
    rollouts = list(range(world.num_rollouts))
    prompt.stage(world, step, rollouts)
    scripts: list[tuple[int, list[tuple[Steering, int, Script]]]] = [
        (r, planned) for r in rollouts if (planned := prompt.scripts(world.start, r))
    ]
    if not scripts:
        return poses
    dt = dynamics.dt
    current = poses_to_frame(world.current(step), origin)
    sizes = world.states[:, world.driven, step][..., [StateField.LENGTH, StateField.WIDTH]].astype(np.float64)
    planned = poses_to_frame(poses, origin)
    out = planned.copy()
    for r, steered in scripts:
        for steering, since, script in steered:
            if len(steering.target.path) < 2:
                continue
            other = steering.other_slot
            other_accel = 0.0 if other is None else float(external_acceleration(world, [other], step, [r])[0, 0])
            memory = prompt.memory.setdefault((r, steering.slot), {})
            now = script_state(steering, since, step, current[r], sizes[r], other_accel, dynamics, 1, 1, memory)
            accel, rate = (float(v) for v in script.plan(now)[0])
            here, then = current[r, steering.slot], planned[r, steering.slot]
            if math.isnan(accel):
                accel = (then[3] - here[3]) / dt
            if math.isnan(rate):
                rate = float(wrap_angle(then[2] - here[2])) / dt
            moved = [float(v) for v in here]
            unicycle_step(moved, accel, rate, dt)
            out[r, steering.slot] = moved
    return poses_to_world(out, origin)
