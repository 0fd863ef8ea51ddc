"""The LangTraj model: scene encoder, language encoder, denoiser and diffusion in unicycle-action space.

The network predicts the clean actions (x0) of every agent from noisy ones; actions are integrated by
the dynamics model into 10 Hz states, and the training loss compares those states with the logged
future in the scene frame, masked by validity (paper 'LangTraj'; docs/design.md, 'The model').

See docs/model.md.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any

import torch
from torch import Tensor, nn

from langtraj.angles import wrap_angle
from langtraj.errors import InputError
from langtraj.model.batch import SceneBatch
from langtraj.model.config import LocalAttention, ModelConfig
from langtraj.model.denoiser import Denoiser
from langtraj.model.diffusion import (
    DiffusionSchedule,
    Guidance,
    classifier_free_guidance,
    cosine_schedule,
    sample,
    timestep_sequence,
)
from langtraj.model.dynamics import DYNAMICS
from langtraj.model.layers import mlp
from langtraj.model.rolling import RollingSchedule, denoise_between, shift_plan
from langtraj.model.scene_encoder import MapContext, SceneContext, SceneEncoder
from langtraj.model.targets import fit_actions
from langtraj.model.text_encoder import TextEncoder
from langtraj.scenario.types import AgentType


class LangTraj(nn.Module):
    """Denoising diffusion over all agents' future actions, conditioned on the scene and on text."""

    def __init__(self, config: ModelConfig):
        super().__init__()
        self.config = config
        d = config.hidden_dim
        self.encoder = SceneEncoder(config)
        self.denoiser = Denoiser(config)
        self.dynamics = DYNAMICS.create(config.dynamics)
        # The schedule's tables live on the model's device (buffers), so no step copies them there.
        schedule = cosine_schedule(config.diffusion_steps)
        for name, table in vars(schedule).items():
            self.register_buffer(f"schedule_{name}", table, persistent=False)
        self.text_encoder = TextEncoder(config.text, d) if config.use_text else None
        self.null_condition = nn.Parameter(torch.zeros(d))
        self.fuse = mlp(2 * d, d, d)
        self.register_buffer("action_scale", torch.tensor(config.action_scale, dtype=torch.float32), persistent=False)
        self._compiled: dict[str, Callable[..., Any]] = {}  # `compile_steps`: plain functions, not submodules

    @property
    def rolling(self) -> RollingSchedule | None:
        """The rolling plan's levels (`model.rolling`) for a model trained with `rolling_group`; None otherwise."""
        group = self.config.rolling_group
        return RollingSchedule(self.config.num_actions, self.config.diffusion_steps, group) if group else None

    @property
    def schedule(self) -> DiffusionSchedule:
        """The diffusion schedule (cosine, K = `diffusion_steps`), its tables on the model's device."""
        return DiffusionSchedule(self.schedule_betas, self.schedule_alphas, self.schedule_alphas_cumprod)

    def compile_steps(self, *, training: bool = True, sampling: bool = True, mode: str = "default") -> LangTraj:
        """Compile, in place, with `torch.compile` (`mode`: "reduce-overhead" adds CUDA graphs): with `training`,
        the training step's network part (`loss` past its target actions, random draws and text encoder); with
        `sampling`, the denoiser that every sampling step calls. Weights, their names and results (to float
        rounding) stay; the first call of each shape compiles. See docs/model.md, 'Fewer, bigger kernels'."""
        if training:
            self._compiled["loss"] = torch.compile(self._denoising_loss, mode=mode)
        if sampling:
            self._compiled["denoise"] = torch.compile(self.denoiser.forward, mode=mode)
        return self

    @property
    def compiled(self) -> bool:
        """Whether `compile_steps` compiled this model's steps."""
        return bool(self._compiled)

    def _denoise(self, *args: Any) -> Tensor:
        """The denoiser, compiled when `compile_steps` asked for it."""
        return self._compiled.get("denoise", self.denoiser)(*args)

    # ------------------------------------------------------------------ conditioning
    def language(
        self,
        batch: SceneBatch,
        scene: SceneContext,
        *,
        drop_text: bool = False,
        embedded: tuple[Tensor, Tensor] | None = None,
    ) -> Tensor:
        """E_L [B, A, D]: each agent's sentence embedding (or the null condition) fused with its scene token.
        `embedded`: the text encoder's output for `batch.text`, when already computed (closed-loop
        training encodes a batch's sentences once for all its replans)."""
        b, a = batch.agent_valid.shape
        text = self.null_condition.expand(b, a, -1)
        if self.text_encoder is not None and not drop_text:
            vectors, has_text = embedded if embedded is not None else self.text_encoder(batch.text)
            text = torch.where(has_text[..., None], vectors, text)
        return self.fuse(torch.cat([scene.agent_tokens, text], dim=-1))

    # ------------------------------------------------------------------ actions <-> network units
    def to_units(self, actions: Tensor) -> Tensor:
        return actions / self.action_scale

    def from_units(self, x: Tensor) -> Tensor:
        return x * self.action_scale

    @property
    def horizon_steps(self) -> int:
        """Scenario steps (10 Hz) the model's N actions cover: 80 for the 16-action model, 40 for 8."""
        return self.config.num_actions * self.dynamics.steps_per_action

    def target_actions(self, batch: SceneBatch) -> tuple[Tensor, Tensor]:
        """Clean actions fitted to the logged future's first `horizon_steps` steps by inverse dynamics, in
        network units, and where they are defined: [B, A, N, 2], bool [B, A, N]. Read from the batch when it
        carries them for this horizon (a feature store fits them once, `model.targets`), else fitted here."""
        stored = batch.target_actions
        if stored is not None and batch.target_valid is not None and stored.shape[-2] == self.config.num_actions:
            return self.to_units(stored).clamp(-4.0, 4.0), batch.target_valid & batch.agent_valid[..., None]
        return self.fit_actions(batch.current_state, batch.future, batch.future_valid, batch.agent_valid)

    def fit_actions(
        self, current: Tensor, future: Tensor, future_valid: Tensor, agent_valid: Tensor
    ) -> tuple[Tensor, Tensor]:
        """Network-unit actions [B, A, N, 2] that take `current` [B, A, 4] along the first `horizon_steps`
        steps of `future` [B, A, >= T, 3], and where they are defined (bool [B, A, N])."""
        actions, valid = fit_actions(self.dynamics, current, future, future_valid, agent_valid, self.config.num_actions)
        return self.to_units(actions).clamp(-4.0, 4.0), valid

    def rollout(self, batch: SceneBatch, x0: Tensor) -> Tensor:
        """States [B, A, T, 4] (x, y, heading, speed) from network-unit actions [B, A, N, 2]."""
        return self.integrate(batch.current_state, batch.agent_type, batch.agent_size[..., 0], x0)

    def integrate(self, current_state: Tensor, agent_type: Tensor, agent_length: Tensor, x0: Tensor) -> Tensor:
        """States from the current states [B, A, 4], agent types and lengths (m) [B, A] and network-unit actions
        [B, A, N, 2]; each agent turns no tighter than `max_curvature` (without it, an undertrained model's small
        yaw rates turn a stopped car on the spot, a bus pivots like a car, and in closed loop such errors add up)."""
        return self.dynamics(current_state, self.from_units(x0), self.max_curvature(agent_type, agent_length).to(x0))

    def max_curvature(self, agent_type: Tensor, agent_length: Tensor) -> Tensor:
        """Each agent's tightest turn [B, A] (1/m): vehicles' by their length (`ModelConfig.vehicle_curvature`), inf
        for pedestrians and cyclists."""
        limit = self.config.vehicle_curvature(agent_length)
        return torch.where(agent_type == int(AgentType.VEHICLE), limit, torch.inf)

    # ------------------------------------------------------------------ training
    def loss(
        self,
        batch: SceneBatch,
        *,
        text_weight: float = 1.0,
        generator: torch.Generator | None = None,
        with_states: bool = False,
    ) -> dict[str, Tensor]:
        """Diffusion loss at a random step per scene: position (and heading) error of the states that
        the predicted clean actions produce, against the log, masked by validity. Agents that carry a
        sentence count `text_weight` times (their share of the batch is small, and they alone teach
        the model to follow text). `with_states`: the dict also holds those states [B, A, T, 4] under
        "states" and each scene's signal level abar_k [B] under "signal" (for penalties on the states,
        `training.penalties`, which weigh a scene by how much of its clean sample the network saw)."""
        x0, _ = self.target_actions(batch)
        b = x0.shape[0]
        k = torch.randint(0, self.schedule.num_steps, (b,), device=x0.device, generator=generator)
        if self.rolling is not None:  # per-action levels: a share of the scenes at a rolling plan's
            levels = self.rolling.training_levels(b, generator).to(x0.device)
            rolling = torch.rand(b, device=x0.device, generator=generator) < self.config.rolling_fraction
            k = torch.where(rolling[:, None], levels, k[:, None].expand(b, self.config.num_actions))
        noise = torch.randn(x0.shape, device=x0.device, generator=generator)
        embedded = self.text_encoder(batch.text) if self.text_encoder is not None else None
        text_weight_of = None
        if text_weight != 1.0 and embedded is not None:
            text_weight_of = torch.where(embedded[1] & batch.agent_valid, text_weight, 1.0)
        core = self._compiled.get("loss", self._denoising_loss)
        out = core(_tensors_only(batch), x0, k, noise, embedded, text_weight_of)
        if with_states:
            signal = self.schedule_alphas_cumprod[k].to(x0.dtype)
            return {**out, "signal": signal.mean(-1) if signal.dim() == 2 else signal}
        del out["states"]
        return out

    def _denoising_loss(
        self,
        batch: SceneBatch,
        x0: Tensor,
        k: Tensor,
        noise: Tensor,
        embedded: tuple[Tensor, Tensor] | None,
        text_weight_of: Tensor | None,
    ) -> dict[str, Tensor]:
        """`loss` from its draws on: tensors in, tensors out, the part `compile_steps` compiles. `embedded`: the
        text encoder's output for the batch's sentences; `text_weight_of` [B, A]: each agent's loss weight. `k`: each
        scene's step [B], or each action's [B, N] (a rolling model)."""
        x_k = self.schedule.q_sample(x0, k[:, None].expand(x0.shape[:3]) if k.dim() == 2 else k, noise)
        scene = self.encoder(batch)
        language = self.language(batch, scene, drop_text=embedded is None, embedded=embedded)
        pred = self.denoiser(x_k, k, scene, language)
        states = self.rollout(batch, pred)
        horizon = self.horizon_steps
        future = batch.future[:, :, :horizon]
        mask = batch.future_valid[:, :, :horizon] & batch.agent_valid[..., None]
        weight = mask.float()
        if text_weight_of is not None:
            weight = weight * text_weight_of[..., None]
        count = weight.sum().clamp(min=1.0)
        position = ((states[..., :2] - future[..., :2]) ** 2).sum(-1)
        dh = wrap_angle(states[..., 2] - future[..., 2])
        position_loss = (position * weight).sum() / count
        heading_loss = (dh**2 * weight).sum() / count
        ade = (torch.sqrt(position + 1e-9) * weight).sum() / count
        parts = {"position": position_loss, "heading": heading_loss, "ade": ade, "states": states}
        return {"loss": position_loss + heading_loss, **parts}

    # ------------------------------------------------------------------ sampling
    @torch.no_grad()
    def sample(
        self,
        batch: SceneBatch,
        num_samples: int = 1,
        *,
        steps: int | None = None,
        eta: float = 0.0,
        guidance_weight: float = 0.0,
        guidance: Guidance | None = None,
        generator: torch.Generator | None = None,
        noise: Callable[[tuple[int, ...]], Tensor] | None = None,
        map_context: MapContext | None = None,
        local: LocalAttention | None = None,
        start: Tensor | None = None,
        start_steps: int | None = None,
    ) -> tuple[Tensor, Tensor]:
        """`num_samples` joint futures per scene: states [S, B, A, T, 4] and actions [S, B, A, N, 2].

        `steps` DDIM steps (default K); `guidance_weight` w is classifier-free guidance (w = -1: no text,
        0: text as given, > 0: stronger); `guidance` modifies x0 at every step (cost guidance). Its x0 rows
        are sample-major (all scenes of sample 0, then sample 1, ...), as are the rows `noise(shape)`
        must draw when given (instead of `generator`). `map_context` is the encoded map when the caller
        keeps it (`SceneEncoder.encode_map`; a simulation's map is fixed). `local`: attend locally in
        scenes larger than its budgets (a model driving more agents than it was trained with). `start`
        (actions [B, A, N, 2], physical, one plan per scene) warm-starts every sample of a scene: the last
        `start_steps` of the `steps` run from it, noised (`model.diffusion.sample`).
        """
        denoise, expanded = self._denoiser(batch, num_samples, guidance_weight, map_context, local)
        b, a = expanded.agent_valid.shape
        shape = (b, a, self.config.num_actions, 2)
        if start is not None:
            start = _repeat(self.to_units(start), num_samples)
        x0 = sample(
            denoise,
            shape,
            self.schedule,
            num_inference_steps=steps or self.schedule.num_steps,
            eta=eta,
            guidance=guidance,
            generator=generator,
            noise=noise,
            device=expanded.agent_valid.device,
            start=start,
            start_steps=start_steps,
        )
        states = self.rollout(expanded, x0)
        n = batch.batch_size
        return states.reshape(num_samples, n, *states.shape[1:]), self.from_units(x0).reshape(num_samples, n, a, -1, 2)

    @torch.no_grad()
    def roll(
        self,
        batch: SceneBatch,
        num_samples: int,
        plan: Tensor | None,
        *,
        steps: int,
        noise: Callable[[tuple[int, ...]], Tensor],
        guidance_weight: float = 0.0,
        guidance: Guidance | None = None,
        map_context: MapContext | None = None,
        local: LocalAttention | None = None,
    ) -> tuple[Tensor, Tensor, Tensor]:
        """One replan of a rolling plan (`model.rolling`): states [S, B, A, T, 4] and actions [S, B, A, N, 2] of the
        plan's x0 prediction, whose first `rolling_group` actions are clean, and the plan [S * B, A, N, 2] (network
        units, sample-major) for the next replan, shifted by them. `plan` None: a cold start from `noise(shape)`
        in `steps` calls; otherwise one call. The cold start's calls pass `guidance` their step of the sequence; every
        rolling call (and the cold start's last) the last of the `steps` sampler steps, so hooks that act at the final
        steps act at each replan. Steps are deterministic DDIM; `noise` draws the start and the fresh end. Other
        arguments as `sample`."""
        rolling = self.rolling
        if rolling is None:
            raise InputError(
                "this checkpoint was not trained to roll its plans (model.rolling_group is 0)", where="rolling"
            )
        denoise, expanded = self._denoiser(batch, num_samples, guidance_weight, map_context, local)
        b, a = expanded.agent_valid.shape
        shape = (b, a, self.config.num_actions, 2)
        last = timestep_sequence(self.schedule.num_steps, num_inference_steps=steps)[-1]
        calls = rolling.cold_start(steps) if plan is None else [(rolling.before(), rolling.after())]
        x = noise(shape) if plan is None else plan

        def denoise_levels(x_k: Tensor, levels: Tensor) -> Tensor:
            return denoise(x_k, levels[None].expand(b, -1))

        x0 = x
        for i, (levels, target) in enumerate(calls):
            hook_step = last if i == len(calls) - 1 else int(levels.min())
            x, x0 = denoise_between(
                denoise_levels, x, levels, target, self.schedule, guidance=guidance, guidance_step=hook_step
            )
        nxt = shift_plan(x, rolling.group, noise(shape))
        states = self.rollout(expanded, x0)
        n = batch.batch_size
        actions = self.from_units(x0).reshape(num_samples, n, a, -1, 2)
        return states.reshape(num_samples, n, *states.shape[1:]), actions, nxt

    def _denoiser(
        self,
        batch: SceneBatch,
        num_samples: int,
        guidance_weight: float,
        map_context: MapContext | None,
        local: LocalAttention | None,
    ) -> tuple[Callable[[Tensor, Tensor], Tensor], SceneBatch]:
        """The x0 prediction (x_k, k) -> x0 of `num_samples` samples per scene of `batch` (sample-major rows), with
        classifier-free guidance `guidance_weight`, and the batch repeated to those rows. The scene and its sentences
        are encoded once; every step and sample shares them and the relative-pose terms."""
        base = self.encoder(batch, map_context, local)
        conditional = _repeat(self.language(batch, base), num_samples)
        unconditional = (
            _repeat(self.language(batch, base, drop_text=True), num_samples) if guidance_weight != 0.0 else None
        )
        scene = base.repeat(num_samples)
        expanded = _repeat_batch(batch, num_samples)
        cache = self.denoiser.pose_cache(base)  # per scene, shared by every step and sample

        def denoise(x_k: Tensor, k: Tensor) -> Tensor:
            x0 = self._denoise(x_k, k, scene, conditional, cache)
            if unconditional is not None:
                uncond = self._denoise(x_k, k, scene, unconditional, cache)
                x0 = classifier_free_guidance(x0, uncond, guidance_weight)
            return x0

        return denoise, expanded


def _tensors_only(batch: SceneBatch) -> SceneBatch:
    """The batch without its per-scene Python lists (sentences, ids): what the network reads, so that a compiled
    step depends on tensors alone (a list's contents would be guarded on, and change every batch)."""
    return replace(batch, text=[], scenario_id=[])


def _repeat(value: Tensor, times: int) -> Tensor:
    """`value` [B, ...] repeated sample-major to [times * B, ...]."""
    return value if times == 1 else value.repeat(times, *([1] * (value.dim() - 1)))


def _repeat_batch(batch: SceneBatch, times: int) -> SceneBatch:
    """The batch with every scene repeated `times` times (sample-major: all scenes, then again)."""
    if times == 1:
        return batch
    fields = {}
    for name, value in vars(batch).items():
        if isinstance(value, Tensor):
            fields[name] = _repeat(value, times)
        elif value is not None:
            fields[name] = list(value) * times
    return replace(batch, **fields)
