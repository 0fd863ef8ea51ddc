"""Open-loop sampling from a trained model on one scenario: futures for the agents the model drives,
in world coordinates, optionally conditioned on a typed `@id` prompt (docs/model.md, 'Sampling')."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import torch

from langtraj.angles import wrap_angle
from langtraj.frames import poses_to_world
from langtraj.model.config import SampleConfig
from langtraj.model.features import collate_scenes, scene_sample
from langtraj.model.langtraj import LangTraj
from langtraj.rollouts.baselines import generate_baseline
from langtraj.rollouts.container import Rollouts
from langtraj.scenario.model import Agents, Scenario
from langtraj.scenario.types import StateField
from langtraj.sim.prompts import check_prompt_driven, user_prompt_entry


@dataclass(frozen=True)
class OpenLoopSamples:
    """`states[s, a, t]` = (x, y, heading, speed) in world coordinates of scenario agent `agents[a]` at
    future step t of sample s; `conditioned` are the track ids that carried text."""

    agents: np.ndarray  # int64 [A]: scenario agent indices, most important first
    states: np.ndarray  # float64 [S, A, T, 4]
    conditioned: tuple[int, ...]

    def scenario_with(self, scenario: Scenario, sample: int = 0) -> Scenario:
        """The scenario with the driven agents' future replaced by sample `sample` (for rendering); their
        steps past the model's horizon are invalid (never the log's)."""
        c = scenario.current_index
        steps = min(self.states.shape[2], scenario.num_steps - c - 1)
        states = scenario.agents.states.copy()
        valid = scenario.agents.valid.copy()
        future = self.states[sample, :, :steps]
        cols = slice(c + 1, c + 1 + steps)
        block = states[self.agents, cols]
        Agents.write_poses(block, future)
        states[self.agents, cols] = block
        sizes = [StateField.Z, StateField.LENGTH, StateField.WIDTH, StateField.HEIGHT]
        states[np.ix_(self.agents, np.arange(cols.start, cols.stop), sizes)] = states[self.agents, c][:, None, sizes]
        valid[self.agents, cols] = True
        valid[self.agents, cols.stop :] = False  # past the model's horizon (4 s for a closed-loop model): unknown
        return replace(scenario, agents=replace(scenario.agents, states=states, valid=valid))


def sample_open_loop(
    model: LangTraj,
    scenario: Scenario,
    data: SampleConfig,
    *,
    prompt: str | None = None,
    num_samples: int = 6,
    steps: int = 10,
    guidance_weight: float = 0.0,
    seed: int = 0,
) -> OpenLoopSamples:
    """`num_samples` joint futures of the scenario's most important agents (up to the model's
    `max_agents`; the rest are not driven). A prompt naming an agent outside that set is an error."""
    entry = user_prompt_entry(scenario, prompt) if prompt is not None else None
    row = scene_sample(scenario, data)
    if entry is not None:
        for slot, sentence in entry.sentences(row["agent_id"][row["agent_id"] >= 0].tolist()).items():
            row["text"][slot] = sentence
    batch = collate_scenes([row])
    ids = batch.agent_id[0].numpy()
    if entry is not None:
        check_prompt_driven(entry, ids[ids >= 0].tolist(), data.max_agents)
    model.eval()
    generator = torch.Generator().manual_seed(seed)
    states, _ = model.sample(batch, num_samples, steps=steps, guidance_weight=guidance_weight, generator=generator)
    real = ids >= 0
    scene = states[:, 0, real].double().numpy()  # [S, A, T, 4] in the scene frame
    world = poses_to_world(scene, tuple(batch.origin[0].double().tolist()))
    agents = np.array([scenario.agents.index_of(int(i)) for i in ids[real]], np.int64)
    conditioned = tuple(int(i) for i, t in zip(ids.tolist(), batch.text[0], strict=False) if t is not None and i >= 0)
    return OpenLoopSamples(agents, world, conditioned)


def open_loop_rollouts(scenario: Scenario, samples: OpenLoopSamples) -> Rollouts:
    """WOSAC rollouts (one per sample) for every sim agent: the driven agents follow the samples, the
    others (beyond the model's agent budget) keep constant velocity; height stays at the current one."""
    rollouts = generate_baseline("constant_velocity", scenario, samples.states.shape[0])
    column = {int(a): i for i, a in enumerate(rollouts.object_id)}
    cols = np.array([column[int(scenario.agents.ids[a])] for a in samples.agents], np.int64)
    x, y, heading = rollouts.x.copy(), rollouts.y.copy(), rollouts.heading.copy()
    steps = min(x.shape[-1], samples.states.shape[2])
    x[:, cols, :steps] = samples.states[..., :steps, 0]
    y[:, cols, :steps] = samples.states[..., :steps, 1]
    heading[:, cols, :steps] = wrap_angle(samples.states[..., :steps, 2])
    z = np.broadcast_to(
        scenario.agents.states[samples.agents, scenario.current_index, StateField.Z][None, :, None],
        (x.shape[0], len(cols), x.shape[-1]),
    )
    zz = rollouts.z.copy()
    zz[:, cols] = z
    return replace(rollouts, x=x, y=y, z=zz, heading=heading)
