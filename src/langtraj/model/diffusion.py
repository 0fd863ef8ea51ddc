"""Gaussian diffusion over action trajectories: the cosine schedule, DDPM / DDIM steps and the sampler.

The denoiser predicts the clean sample x0 (not the noise), as in LangTraj ("Denoising Process"
appendix). Timesteps are 0-based tensor indices k = 0 .. K-1; index k is the paper's step k+1, so
`alphas_cumprod[k]` = prod_{j<=k} alpha_j and "stepping below 0" means returning the clean sample.

See docs/model.md.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import torch
from torch import Tensor

from langtraj.errors import InputError

Denoiser = Callable[[Tensor, Tensor], Tensor]
"""(x_k [B, ...], k long [B]) -> predicted x0 [B, ...]."""
Guidance = Callable[[Tensor, Tensor, Tensor], Tensor]
"""(x0_pred, k long [B], x_k) -> a modified x0 of the same shape (e.g. x0 minus a scaled cost gradient):
the hook for cost guidance (`langtraj.guidance.step`)."""


DENOISING_STEP = "langtraj.denoising_step"
GUIDANCE_STEP = "langtraj.guidance_step"
"""Profiler ranges around each sampling step's network call (`sample`) and around each step's cost guidance
where it applies (`guidance.step`), which `benchmarks/sample_ops.py` counts the operations of."""


def _index(values: Tensor, k: Tensor | int, like: Tensor) -> Tensor:
    """values[k] as `like`'s dtype/device, with trailing singleton dims so it broadcasts against `like`.

    `k` is an int or a long tensor whose shape is a prefix of like.shape (e.g. [B]); k = -1 reads 1.0
    (the clean sample, "alpha-bar before step 0").
    """
    k_t = torch.as_tensor(k, device=values.device, dtype=torch.long)
    padded = torch.cat([values.new_ones(1), values])
    out = padded[k_t + 1].to(device=like.device, dtype=like.dtype)
    return out.reshape(*out.shape, *([1] * (like.ndim - out.ndim)))


@dataclass(frozen=True)
class DiffusionSchedule:
    """Per-step betas, alphas = 1 - betas and alphas_cumprod (float64 [K]), with the q / posterior / DDIM maths."""

    betas: Tensor
    alphas: Tensor
    alphas_cumprod: Tensor

    @property
    def num_steps(self) -> int:
        return self.betas.shape[0]

    def q_sample(self, x0: Tensor, k: Tensor | int, noise: Tensor) -> Tensor:
        """x_k ~ q(x_k | x0) = N(sqrt(abar_k) x0, (1 - abar_k) I), with the given standard normal `noise`."""
        abar = _index(self.alphas_cumprod, k, x0)
        return abar.sqrt() * x0 + (1 - abar).sqrt() * noise

    def posterior_mean_variance(
        self, x0: Tensor, x_k: Tensor, k: Tensor | int, k_prev: Tensor | int | None = None
    ) -> tuple[Tensor, Tensor]:
        """Mean and variance of the DDPM posterior q(x_{k_prev} | x_k, x0); k_prev defaults to k - 1.

        For k_prev = k - 1 this is mean = sqrt(abar_{k-1}) beta_k / (1 - abar_k) x0
        + sqrt(alpha_k) (1 - abar_{k-1}) / (1 - abar_k) x_k (the paper's mu_theta) and variance
        beta_k (1 - abar_{k-1}) / (1 - abar_k); a larger jump uses alpha = abar_k / abar_{k_prev}.
        """
        k_t = torch.as_tensor(k, dtype=torch.long)
        k_prev_t = k_t - 1 if k_prev is None else torch.as_tensor(k_prev, dtype=torch.long)
        abar = _index(self.alphas_cumprod, k_t, x_k)
        abar_prev = _index(self.alphas_cumprod, k_prev_t, x_k)
        alpha = abar / abar_prev
        beta = 1 - alpha
        mean = (abar_prev.sqrt() * beta * x0 + alpha.sqrt() * (1 - abar_prev) * x_k) / (1 - abar)
        variance = beta * (1 - abar_prev) / (1 - abar)
        return mean, variance.expand_as(mean)

    def ddim_step(
        self,
        x0_pred: Tensor,
        x_k: Tensor,
        k: Tensor | int,
        k_prev: Tensor | int,
        eta: float = 0.0,
        noise: Tensor | None = None,
    ) -> Tensor:
        """One DDIM step (Song et al. 2021, eq. 12) from x_k to x_{k_prev} given the predicted x0.

        sigma = eta sqrt((1 - abar_prev) / (1 - abar_k)) sqrt(1 - abar_k / abar_prev); eta = 0 is
        deterministic, eta = 1 with k_prev = k - 1 is the DDPM posterior. k_prev = -1 returns x0_pred.
        """
        abar = _index(self.alphas_cumprod, k, x_k)
        abar_prev = _index(self.alphas_cumprod, k_prev, x_k)
        eps = (x_k - abar.sqrt() * x0_pred) / (1 - abar).sqrt()
        sigma2 = eta**2 * (1 - abar_prev) / (1 - abar) * (1 - abar / abar_prev)
        direction = (1 - abar_prev - sigma2).clamp(min=0).sqrt() * eps
        out = abar_prev.sqrt() * x0_pred + direction
        if eta > 0:
            if noise is None:
                noise = torch.randn_like(x_k)
            out = out + sigma2.sqrt() * noise
        return out


def cosine_schedule(num_steps: int = 100, s: float = 0.008, max_beta: float = 0.999) -> DiffusionSchedule:
    """The cosine schedule of Nichol & Dhariwal (2021), as LangTraj uses (K = 100, s = 0.008).

    f(t) = cos^2(((t / K) + s) / (1 + s) * pi / 2); beta_k = min(1 - f(k+1) / f(k), max_beta) for the
    0-based index k, so alphas_cumprod[k] = f(k+1) / f(0) until the clip bites (only at the last step).
    """
    if num_steps < 1:
        raise InputError(f"num_steps must be >= 1, got {num_steps}")
    t = torch.arange(num_steps + 1, dtype=torch.float64)
    f = torch.cos(((t / num_steps) + s) / (1 + s) * math.pi / 2) ** 2
    betas = (1 - f[1:] / f[:-1]).clamp(max=max_beta)
    alphas = 1 - betas
    return DiffusionSchedule(betas=betas, alphas=alphas, alphas_cumprod=torch.cumprod(alphas, 0))


def timestep_sequence(
    num_steps: int, *, stride: int | None = None, num_inference_steps: int | None = None
) -> list[int]:
    """Descending timesteps K-1, K-1-stride, ... (>= 0): the sampler visits each, then returns its x0.

    Starting at K-1 keeps the start consistent with N(0, I). `num_inference_steps` n sets stride = K // n
    and keeps the first n: K = 100, n = 5 -> [99, 79, 59, 39, 19]; stride 1 visits every step.
    """
    if (stride is None) == (num_inference_steps is None):
        if stride is None:
            stride = 1
        else:
            raise InputError("give either stride or num_inference_steps, not both")
    if num_inference_steps is not None:
        if not 1 <= num_inference_steps <= num_steps:
            raise InputError(f"num_inference_steps must be in [1, {num_steps}], got {num_inference_steps}")
        stride = num_steps // num_inference_steps
        return list(range(num_steps - 1, -1, -stride))[:num_inference_steps]
    assert stride is not None
    if stride < 1:
        raise InputError(f"stride must be >= 1, got {stride}")
    return list(range(num_steps - 1, -1, -stride))


def sample(
    denoise: Denoiser,
    shape: tuple[int, ...] | torch.Size,
    schedule: DiffusionSchedule,
    *,
    num_inference_steps: int | None = None,
    stride: int | None = None,
    eta: float = 0.0,
    sampler: Literal["ddim", "ddpm"] = "ddim",
    guidance: Guidance | None = None,
    generator: torch.Generator | None = None,
    noise: Callable[[tuple[int, ...]], Tensor] | None = None,
    device: torch.device | str | None = None,
    dtype: torch.dtype = torch.float32,
    start: Tensor | None = None,
    start_steps: int | None = None,
) -> Tensor:
    """Reverse diffusion from x_{K-1} ~ N(0, I) of `shape` ([B, ...]); returns the last x0 prediction.

    A warm start: with `start` (a clean x0 of `shape`) and `start_steps` n, only the last n timesteps of the
    sequence run, from `start` noised to the first of them by q(x_k | x0) (SDEdit): fewer network calls,
    and a sample that stays near `start` as far as the noise level allows. n = the whole sequence starts
    from `start` noised to the top step, a cold start up to sqrt(abar_{K-1}) x `start`.

    At each timestep of `timestep_sequence` (default stride 1): x0 = denoise(x_k, k); if `guidance` is
    given, x0 = guidance(x0, k, x_k) (the hook for cost-gradient guidance: it must return a modified x0
    of the same shape); then x_k steps to the next timestep of the sequence by DDIM (`eta`) or by the
    DDPM posterior q(x_prev | x_k, x0) (its generalisation to strides). Noise comes from `generator`,
    or from `noise(shape)` when given (e.g. one generator per batch row, so that a row's draws do not
    depend on the rows beside it).
    """
    if sampler not in ("ddim", "ddpm"):
        raise InputError(f"unknown sampler {sampler!r}; known: ddim, ddpm")
    steps = timestep_sequence(schedule.num_steps, stride=stride, num_inference_steps=num_inference_steps)
    if generator is not None and device is None:
        device = generator.device
    shape = tuple(shape)

    def randn() -> Tensor:
        if noise is not None:
            return noise(shape).to(device=device, dtype=dtype)
        return torch.randn(shape, generator=generator, device=device, dtype=dtype)

    x = randn()
    if start is not None:
        if start_steps is None or not 1 <= start_steps <= len(steps):
            raise InputError(f"start_steps must be in [1, {len(steps)}] with a warm start, got {start_steps}")
        if tuple(start.shape) != shape:
            raise InputError(f"a warm start must have the sample's shape {shape}, got {tuple(start.shape)}")
        steps = steps[len(steps) - start_steps :]
        x = schedule.q_sample(start.to(device=x.device, dtype=dtype), steps[0], x)
    x0 = x
    for i, k in enumerate(steps):
        k_prev = steps[i + 1] if i + 1 < len(steps) else -1
        k_batch = torch.full(shape[:1], k, dtype=torch.long, device=x.device)
        with torch.profiler.record_function(DENOISING_STEP):
            x0 = denoise(x, k_batch)
        if guidance is not None:
            x0 = guidance(x0, k_batch, x)
        if k_prev < 0:
            break
        if sampler == "ddim":
            x = schedule.ddim_step(x0, x, k, k_prev, eta=eta, noise=randn() if eta > 0 else None)
        else:
            mean, variance = schedule.posterior_mean_variance(x0, x, k, k_prev)
            x = mean + variance.sqrt() * randn()
    return x0


def classifier_free_guidance(x0_cond: Tensor, x0_uncond: Tensor, w: float | Tensor) -> Tensor:
    """x0 = x0_uncond + (1 + w) (x0_cond - x0_uncond) = (1 + w) x0_cond - w x0_uncond (LangTraj's eq.).

    The paper's convention: w = -1 is unconditional, w = 0 conditional, w > 0 extrapolates past the
    conditional prediction (its CFG study uses w in [-1, 1]).
    """
    return x0_uncond + (1 + w) * (x0_cond - x0_uncond)
