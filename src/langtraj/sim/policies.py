"""Policies: what decides the driven agents' next states at each replan of a closed-loop simulation.

One interface, registered by name: LangTraj (a checkpoint, optionally with text, classifier-free and
cost guidance), constant velocity, log replay, and the CTG++-style baseline (LangTraj without text,
steered by a fixed library of guidance costs per prompt label, the role LLM-written costs play in the
paper's comparison). A policy `drives` some sim agents; the world moves every other agent along its log.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Sequence
from dataclasses import replace
from typing import ClassVar

import numpy as np
import torch
from torch import Tensor

from langtraj.errors import InputError
from langtraj.frames import poses_to_frame, poses_to_world
from langtraj.guidance import GuidanceScene, GuidanceTerm, reconstruction_guidance
from langtraj.guidance.library import terms_for_prompt
from langtraj.interdrive.dataset import PromptEntry
from langtraj.model.langtraj import LangTraj
from langtraj.model.open_loop import check_prompt_driven
from langtraj.registry import Registry
from langtraj.scenario.model import STEP_SECONDS, Scenario
from langtraj.scenario.selection import prioritized_agents
from langtraj.sim.selection import SELECTORS
from langtraj.sim.world import SimWorld
from langtraj.training.data import SampleConfig, build_sample, collate_scenes, map_polylines, scene_frame


class Policy(ABC):
    """Plans the driven agents' states (world x, y, heading, speed at 10 Hz) from each rollout's past."""

    name: ClassVar[str]

    def drives(self, scenario: Scenario, sim_agents: np.ndarray) -> np.ndarray:
        """Scenario rows this policy drives, a subset of `sim_agents` (default: all of them)."""
        return sim_agents

    def reset(self, world: SimWorld, seed: int) -> None:  # noqa: B027 (optional hook)
        """Prepare for a new simulation of `world` (per-rollout random streams, cached map, ...)."""

    @abstractmethod
    def plan(self, world: SimWorld, step: int, horizon: int) -> np.ndarray:
        """States [R, A_driven, >= horizon, 4] for steps step+1 ... of every rollout."""


POLICIES: Registry[Policy] = Registry("policy")


@POLICIES.register
class ConstantVelocityPolicy(Policy):
    """Every sim agent keeps its current heading and speed (replanned from the simulated state)."""

    name = "constant_velocity"

    def plan(self, world: SimWorld, step: int, horizon: int) -> np.ndarray:
        now = world.current(step)  # [R, A, 4]
        t = np.arange(1, horizon + 1) * STEP_SECONDS
        x = now[..., None, 0] + now[..., None, 3] * np.cos(now[..., None, 2]) * t
        y = now[..., None, 1] + now[..., None, 3] * np.sin(now[..., None, 2]) * t
        shape = x.shape
        return np.stack(
            [x, y, np.broadcast_to(now[..., None, 2], shape), np.broadcast_to(now[..., None, 3], shape)], -1
        )


@POLICIES.register
class LogReplayPolicy(Policy):
    """No agent is driven: everyone follows the log (constant velocity past its end)."""

    name = "log_replay"

    def drives(self, scenario: Scenario, sim_agents: np.ndarray) -> np.ndarray:
        return sim_agents[:0]

    def plan(self, world: SimWorld, step: int, horizon: int) -> np.ndarray:
        return np.zeros((world.num_rollouts, 0, horizon, 4))


@POLICIES.register
class LangTrajPolicy(Policy):
    """Samples `candidates` joint futures per rollout from a LangTraj model at each replan and executes
    the one `selector` picks.

    The model drives the `data.max_agents` most important sim agents (`prioritized_agents` at the start:
    objects of interest, the SDC, tracks to predict, then by distance to the SDC), and every replan uses
    the scene frame of the start, so guidance costs and the map stay put. `prompt` conditions the agents it
    mentions; `terms` (agent slots = positions in `driven_ids`) add reconstruction guidance, scaled by
    `guidance_scale`; `guidance_weight` is classifier-free guidance (-1: ignore text). Each rollout draws
    its noise from its own generator seeded by (seed, rollout), so rollouts batched `rollout_batch` at a
    time give what they give one by one.
    """

    name = "langtraj"

    def __init__(
        self,
        model: LangTraj,
        data: SampleConfig,
        *,
        prompt: PromptEntry | None = None,
        terms: Sequence[GuidanceTerm] = (),
        candidates: int = 4,
        steps: int = 5,
        guidance_weight: float = 0.0,
        guidance_scale: float = 1.0,
        selector: str | None = None,
        rollout_batch: int = 0,
        max_grad_norm: float | None = 0.5,
    ):
        if candidates < 1 or steps < 1 or rollout_batch < 0:
            raise InputError(
                f"candidates and steps must be >= 1 and rollout_batch >= 0 (got {candidates}, {steps}, {rollout_batch})"
            )
        if prompt is not None and model.text_encoder is None:
            raise InputError(
                "this checkpoint has no text branch (a stage-1 model); it cannot follow a prompt", where="prompt"
            )
        self.model = model.eval()
        self.data = replace(data, text=prompt is not None, text_dropout=0.0, history_dropout=0.0)
        self.prompt = prompt
        self.base_terms = self.terms = tuple(terms)
        self.candidates, self.steps = candidates, steps
        self.guidance_weight, self.guidance_scale = guidance_weight, guidance_scale
        self.selector_name = selector
        if selector is not None:
            SELECTORS.get(selector, where="selector")
        self.rollout_batch = rollout_batch
        self.max_grad_norm = max_grad_norm

    # ------------------------------------------------------------------ which agents
    def drives(self, scenario: Scenario, sim_agents: np.ndarray) -> np.ndarray:
        return prioritized_agents(scenario, self.data.max_agents)  # valid at the current step: sim agents

    @staticmethod
    def slots(scenario: Scenario, driven: np.ndarray) -> dict[int, int]:
        """Track id -> model slot of every driven agent (what guidance terms and prompts refer to)."""
        return {int(scenario.agents.ids[row]): slot for slot, row in enumerate(driven)}

    # ------------------------------------------------------------------ simulation
    def reset(self, world: SimWorld, seed: int) -> None:
        start = world.scenario_at(0, world.start)
        slots = self.slots(start, world.driven)
        if self.prompt is not None:
            check_prompt_driven(self.prompt, list(slots), self.data.max_agents)
        self.origin = scene_frame(start)
        self.map_arrays = map_polylines(start.road_map, self.origin, self.data)
        device = next(self.model.parameters()).device
        scene = GuidanceScene.from_scenario(start, self.origin, world.driven, num_agents=self.data.max_agents)
        self.scene = scene.to(device)
        self.generators = [torch.Generator().manual_seed(seed * 1_000_003 + r) for r in range(world.num_rollouts)]
        self.terms = self.base_terms + self.prompt_terms(world, slots)
        default = "min_guidance" if self.terms else "min_collision"
        self.selector = SELECTORS.create(self.selector_name or default, where="selector")

    def prompt_terms(self, world: SimWorld, slots: dict[int, int]) -> tuple[GuidanceTerm, ...]:
        """Guidance terms derived from the scene at the start (none here; the baseline's come from labels)."""
        return ()

    def plan(self, world: SimWorld, step: int, horizon: int) -> np.ndarray:
        chunk = self.rollout_batch or world.num_rollouts
        plans = [
            self._plan_rollouts(world, step, list(range(lo, min(lo + chunk, world.num_rollouts))))
            for lo in range(0, world.num_rollouts, chunk)
        ]
        return np.concatenate(plans, axis=0)[:, :, : max(horizon, 1)]

    def _plan_rollouts(self, world: SimWorld, step: int, rollouts: list[int]) -> np.ndarray:
        rng = np.random.default_rng(0)  # unused: no augmentation, and the prompt (if any) is fixed
        rows = [
            build_sample(
                world.scenario_at(r, step),
                None,
                self.data,
                rng,
                prompt=self.prompt,
                augment=False,
                agents=world.driven,
                origin=self.origin,
                map_arrays=self.map_arrays,
            )
            for r in rollouts
        ]
        device = next(self.model.parameters()).device
        batch = collate_scenes(rows).to(device)
        m = self.candidates
        generators = [self.generators[r] for r in rollouts]

        def noise(shape: tuple[int, ...]) -> Tensor:  # sample-major rows: [M * R, ...]
            per_rollout = [torch.randn((m, *shape[1:]), generator=g) for g in generators]
            return torch.stack(per_rollout, dim=1).reshape(shape).to(device)

        hook = None
        if self.terms:
            initial = batch.current_state.repeat(m, 1, 1)
            types = batch.agent_type.repeat(m, 1)
            model = self.model
            hook = reconstruction_guidance(
                self.terms,
                self.scene,
                lambda x: model.integrate(initial, types, x),
                scale=self.guidance_scale,
                num_steps=self.model.schedule.num_steps,
                max_grad_norm=self.max_grad_norm,
            )
        states, _ = self.model.sample(
            batch, m, steps=self.steps, guidance_weight=self.guidance_weight, guidance=hook, noise=noise
        )
        choice = self.selector.select(states, self.scene, self.terms)  # states [M, R, A, T, 4], scene frame
        chosen = states[choice, torch.arange(len(rollouts), device=device), : len(world.driven)].double().cpu().numpy()
        return poses_to_world(chosen, self.origin)


@POLICIES.register
class GuidanceBaselinePolicy(LangTrajPolicy):
    """The CTG++-style baseline: the model without text, steered by the library's guidance terms for the
    prompt's interaction subtype and single-agent labels (`langtraj.guidance.library`), in place of the
    loss functions an LLM writes for each instruction in CTG++."""

    name = "guidance_baseline"

    def __init__(self, model: LangTraj, data: SampleConfig, *, prompt: PromptEntry, **kwargs):
        if prompt.subtype is None and not prompt.labels:
            raise InputError(
                "the guidance baseline needs a labelled prompt (an InterDrive subtype or labels)", where="prompt"
            )
        super().__init__(model, data, **kwargs)
        self.labelled = prompt

    def prompt_terms(self, world: SimWorld, slots: dict[int, int]) -> tuple[GuidanceTerm, ...]:
        mentions = {i: slots[t] for i, t in enumerate(self.labelled.mentions[:2]) if t in slots}
        if 0 not in mentions:
            raise InputError(
                f"the prompt's target agent @{self.labelled.mentions[0]} is not driven by the model", where="prompt"
            )
        current = np.zeros((self.data.max_agents, 4))
        current[: len(world.driven)] = poses_to_frame(world.current(world.start)[0], self.origin)
        state = torch.as_tensor(current, dtype=torch.float32)
        return tuple(
            terms_for_prompt(mentions, state, subtype_id=self.labelled.subtype, label_keys=self.labelled.labels)
        )
