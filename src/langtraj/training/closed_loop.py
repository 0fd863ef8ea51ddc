"""Closed-loop training of the diffusion model (paper Algorithm 1; appendix 'Closed-loop Training
Details'; docs/model.md, 'Closed-loop training').

Each training scene is unrolled for `iterations` replans of `replan_actions` actions (2 x 0.5 s) from its
current state. At every replan the ground-truth segment over the model's horizon, expressed as actions
from the *simulated* state, is noised to a level tau ~ U(1, K gamma); the model denoises it in one step
into M candidates; the candidate whose states lie closest to the ground truth is executed through the
dynamics, and the executed steps become the history of the next replan. The loss compares the executed
states of all replans with the ground truth in the scene frame, so the model learns to recover from
where its own earlier choices left it, plus the non-collision cost (weight 0.1) of the executed states.
With probability `teacher_forcing` a sample's agents follow the ground truth, each with probability
`forced_agents`: they execute the inverse-dynamics fit of the log and carry no loss.

The replan start states are detached: a replan learns from the state it is handed, not by changing the
replans before it (no backpropagation through the whole unroll, as in CAT-K's closed-loop fine-tuning).
The M candidates are denoised without a graph; the executed one is denoised again with one (the same
output where dropout is off), so the backward pass costs one candidate, not M.
"""

from __future__ import annotations

import torch
from torch import Tensor

from langtraj.angles import wrap_angle
from langtraj.guidance.costs import NoCollisionCost
from langtraj.guidance.scene import GuidanceScene
from langtraj.model.batch import SceneBatch
from langtraj.model.langtraj import LangTraj
from langtraj.training.config import ClosedLoopConfig


def _rand(shape: tuple[int, ...], generator: torch.Generator | None, device) -> Tensor:
    return torch.rand(shape, generator=generator).to(device)


def forced_agents(batch: SceneBatch, config: ClosedLoopConfig, generator: torch.Generator | None = None) -> Tensor:
    """bool [B, A]: the agents that follow the ground truth (teacher forcing): in a `teacher_forcing`
    share of the scenes, each real agent with probability `forced_agents`."""
    b, a = batch.agent_valid.shape
    device = batch.agent_valid.device
    scene = _rand((b, 1), generator, device) < config.teacher_forcing
    return scene & (_rand((b, a), generator, device) < config.forced_agents) & batch.agent_valid


def select_closest(states: Tensor, target: Tensor, valid: Tensor) -> Tensor:
    """Index [B] of the candidate (states [M, B, A, T, >=2]) whose mean position error against `target`
    [B, A, T, >=2] over `valid` (bool [B, A, T]) is least: one joint candidate per scene."""
    err = torch.linalg.vector_norm(states[..., :2] - target[None, ..., :2], dim=-1)  # [M, B, A, T]
    weight = valid[None].to(err.dtype)
    mean = (err * weight).sum(dim=(2, 3)) / weight.sum(dim=(2, 3)).clamp(min=1.0)
    return mean.argmin(dim=0)


def collision_cost(states: Tensor, batch: SceneBatch) -> Tensor:
    """Mean over scenes of the paper's non-collision cost (disks; `guidance.costs.NoCollisionCost`) of
    states [B, A, T, 4]."""
    cost = NoCollisionCost()
    total = states.new_zeros(())
    for i in range(states.shape[0]):
        scene = GuidanceScene(
            road_edges=states.new_zeros(0, 2, 2),
            lanes=states.new_zeros(0, 1, 2),
            lane_valid=torch.zeros(0, 1, dtype=torch.bool, device=states.device),
            agent_size=batch.agent_size[i],
            agent_valid=batch.agent_valid[i],
        )
        total = total + cost(states[i : i + 1], scene).sum()
    return total / max(states.shape[0], 1)


def closed_loop_loss(
    model: LangTraj, batch: SceneBatch, config: ClosedLoopConfig, *, generator: torch.Generator | None = None
) -> dict[str, Tensor]:
    """Algorithm 1 on one batch: the loss and its parts (position, heading, collision; ade of the executed
    states in metres; `forced`, the share of agents that followed the ground truth)."""
    config.check(model.config.num_actions, batch.future.shape[2] // model.dynamics.steps_per_action)
    device = batch.agent_valid.device
    b, a = batch.agent_valid.shape
    m, n = config.candidates, model.config.num_actions
    execute = config.replan_actions * model.dynamics.steps_per_action
    levels = max(1, round(model.schedule.num_steps * config.noise_ratio))  # tau in 1 .. K gamma (0-based k below)
    forced = forced_agents(batch, config, generator)
    free = batch.agent_valid & ~forced
    embedded = model.text_encoder(batch.text) if model.text_encoder is not None else None  # once per batch
    current, executed_parts = batch, []
    for _ in range(config.iterations):
        x0, _ = model.fit_actions(current.current_state, current.future, current.future_valid, current.agent_valid)
        k = torch.randint(0, levels, (b,), generator=generator).to(device)
        noise = torch.randn((m * b, a, n, 2), generator=generator).to(device)
        x_k = model.schedule.q_sample(x0.repeat(m, 1, 1, 1), k.repeat(m), noise)
        scene = model.encoder(current)
        language = model.language(current, scene, embedded=embedded)
        start, lengths = current.current_state, current.agent_size[..., 0]
        with torch.no_grad():  # the M candidates; only the executed one needs a graph (computed again below)
            cache = model.denoiser.pose_cache(scene)  # per scene, shared by its M candidates (as in sampling)
            pred = model.denoiser(x_k, k.repeat(m), scene.repeat(m), language.repeat(m, 1, 1), cache)
            states = model.integrate(start.repeat(m, 1, 1), current.agent_type.repeat(m, 1), lengths.repeat(m, 1), pred)
            states = states.reshape(m, b, *states.shape[1:])
            horizon = states.shape[3]
            target_valid = current.future_valid[:, :, :horizon] & free[..., None]
            best = select_closest(states, current.future[:, :, :horizon], target_valid)
        rows = best * b + torch.arange(b, device=device)  # sample-major rows of the chosen candidates
        chosen = model.denoiser(x_k[rows], k, scene, language)  # [B, A, N, 2], in the graph
        executed = model.integrate(start, current.agent_type, lengths, chosen)[:, :, :execute]
        truth = model.integrate(start, current.agent_type, lengths, x0)[:, :, :execute].detach()
        executed = torch.where(forced[..., None, None], truth, executed)
        executed_parts.append(executed)
        current = current.advanced(executed.detach())

    executed = torch.cat(executed_parts, dim=2)  # [B, A, iterations * execute, 4]
    steps = executed.shape[2]
    truth = batch.future[:, :, :steps]
    weight = (batch.future_valid[:, :, :steps] & free[..., None]).to(executed.dtype)
    count = weight.sum().clamp(min=1.0)
    position = ((executed[..., :2] - truth[..., :2]) ** 2).sum(-1)
    dh = wrap_angle(executed[..., 2] - truth[..., 2])
    position_loss = (position * weight).sum() / count
    heading_loss = (dh**2 * weight).sum() / count
    collision = collision_cost(executed, batch) if config.collision_weight > 0 else executed.new_zeros(())
    ade = (torch.sqrt(position + 1e-9) * weight).sum() / count
    real = batch.agent_valid.sum().clamp(min=1)
    return {
        "loss": position_loss + heading_loss + config.collision_weight * collision,
        "position": position_loss,
        "heading": heading_loss,
        "collision": collision,
        "ade": ade,
        "forced": forced.sum() / real,
    }
