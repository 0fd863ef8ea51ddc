"""Reconstruction guidance: nudge the denoiser's clean prediction down the gradient of the costs.

x0~ = x0 - alpha * grad_x0 sum_terms weight * J(rollout(x0)) (paper 'Controllable Behavior via
Diffusion Guidance', after Ho et al. and TRACE), applied at every denoising step through the sampler's
guidance hook. The gradient is taken through the differentiable rollout (actions -> states).

See docs/simulation.md.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import torch
from torch import Tensor

from langtraj.errors import InputError
from langtraj.guidance.base import GuidanceTerm
from langtraj.guidance.scene import GuidanceScene
from langtraj.model.diffusion import GUIDANCE_STEP, Guidance


def reconstruction_guidance(
    terms: Sequence[GuidanceTerm],
    scene: GuidanceScene,
    rollout: Callable[[Tensor], Tensor],
    *,
    num_steps: int,
    scale: float = 1.0,
    iterations: int = 1,
    max_grad_norm: float | None = None,
) -> Guidance:
    """The sampler hook (x0 [S, A, N, 2], k, x_k) -> guided x0 for `terms` on `scene`.

    `rollout` maps network-unit actions [S, A, N, 2] to states [S, A, T, 4] (e.g. `lambda x:
    model.rollout(batch, x)`); every row is a candidate of `scene`. `num_steps` is K, the number of
    diffusion steps of the schedule (`model.schedule.num_steps`), which the terms' schedules compare k
    with; k may be an int or one step per row. Each term's gradient is kept only for the agents it
    steers (`cost.agents`) that are valid in the scene (the term sees the other agents' states detached,
    so `rollout` must map each agent's actions to its own states alone, as the dynamics do), and only
    for rows where its schedule is active; one backward pass serves every term. With `max_grad_norm`,
    each agent's summed gradient (over its N x 2 actions) is scaled down to at most that norm.
    `iterations` gradient steps of size `scale` are taken, each from a fresh rollout. Gradients are
    computed even when sampling runs under `torch.no_grad`.
    """
    if num_steps < 1:
        raise InputError(f"num_steps must be >= 1, got {num_steps}")
    if not math.isfinite(scale) or scale < 0:
        raise InputError(f"scale must be finite and >= 0, got {scale}")
    if iterations < 1:
        raise InputError(f"iterations must be >= 1, got {iterations}")
    if max_grad_norm is not None and not max_grad_norm > 0:
        raise InputError(f"max_grad_norm must be > 0, got {max_grad_norm}")
    terms = tuple(terms)

    def guide(x0: Tensor, k: Tensor | int, x_k: Tensor) -> Tensor:
        rows, agents = x0.shape[:2]
        steps = torch.as_tensor(k, dtype=torch.long, device=x0.device).reshape(-1).expand(rows)
        here = scene.to(x0.device)
        active = []
        for term in terms:
            on_rows = term.active(steps, num_steps).to(x0.device)
            if on_rows.any() and term.weight > 0:
                steered = term.cost.agents(agents).to(x0.device) & here.agent_valid
                active.append((term, on_rows.to(x0.dtype), steered[None, :, None, None]))
        if not active or scale == 0:
            return x0
        x = x0.detach()
        with torch.enable_grad(), torch.profiler.record_function(GUIDANCE_STEP):
            for _ in range(iterations):
                x = x.detach().requires_grad_(True)
                states = rollout(x)
                # One backward pass for all terms: each term sees the states of the agents it does not
                # steer detached, so its gradient reaches only its own agents' actions.
                total = None
                for term, on_rows, steered in active:
                    cost = (term.cost(torch.where(steered, states, states.detach()), here) * on_rows).sum()
                    if cost.requires_grad:  # not a cost that does not depend on the states
                        total = cost * term.weight if total is None else total + cost * term.weight
                grad = torch.zeros_like(x)
                if total is not None:
                    (g,) = torch.autograd.grad(total, x, allow_unused=True)
                    if g is not None:
                        grad = g
                if max_grad_norm is not None:
                    norm = torch.linalg.vector_norm(grad, dim=(-2, -1), keepdim=True)
                    grad = grad * (max_grad_norm / norm.clamp(min=max_grad_norm))
                x = x - scale * grad
        return x.detach()

    return guide
