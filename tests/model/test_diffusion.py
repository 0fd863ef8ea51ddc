"""Cosine schedule, forward noising, DDPM / DDIM steps, the sampler and classifier-free guidance."""

from __future__ import annotations

import math

import pytest
import torch

from langtraj.errors import InputError
from langtraj.model.diffusion import (
    classifier_free_guidance,
    cosine_schedule,
    sample,
    timestep_sequence,
)


def f(t: float, steps: int = 100, s: float = 0.008) -> float:
    return math.cos((t / steps + s) / (1 + s) * math.pi / 2) ** 2


def test_cosine_schedule_values() -> None:
    sched = cosine_schedule(100)
    abar = sched.alphas_cumprod
    assert abar.shape == (100,) and sched.num_steps == 100
    assert (abar[1:] < abar[:-1]).all()
    assert abar[0] > 0.999 and abar[-1] < 1e-6
    assert sched.betas.max() <= 0.999
    torch.testing.assert_close(sched.alphas, 1 - sched.betas)
    # Index k is the paper's step k + 1: abar[k] = f(k + 1) / f(0).
    assert abar[49].item() == pytest.approx(f(50) / f(0), rel=1e-12)
    # By hand: cos^2(0.503968 * pi / 2) = 0.493793 over f(0) = cos^2(0.007937 * pi / 2) = 0.999845.
    assert abar[49].item() == pytest.approx(0.49387, abs=1e-4)
    five = cosine_schedule(5)
    assert five.alphas_cumprod[0].item() == pytest.approx(f(1, 5) / f(0, 5), rel=1e-12)


def test_q_sample_statistics() -> None:
    sched = cosine_schedule(100)
    gen = torch.Generator().manual_seed(0)
    x0 = torch.full((200_000,), 2.0, dtype=torch.float64)
    k = 30
    noise = torch.randn(x0.shape, generator=gen, dtype=torch.float64)
    x_k = sched.q_sample(x0, k, noise)
    abar = sched.alphas_cumprod[k].item()
    assert x_k.mean().item() == pytest.approx(2 * math.sqrt(abar), abs=0.01)
    assert x_k.var().item() == pytest.approx(1 - abar, rel=0.02)
    # Per-row timesteps broadcast over trailing dims.
    ks = torch.tensor([0, 99])
    out = sched.q_sample(torch.ones(2, 3, 4), ks, torch.zeros(2, 3, 4))
    torch.testing.assert_close(out[:, 0, 0], sched.alphas_cumprod[ks].sqrt().float())


def test_ddim_eta_one_is_the_ddpm_posterior() -> None:
    sched = cosine_schedule(100)
    gen = torch.Generator().manual_seed(1)
    x0 = torch.randn(4, 16, 2, generator=gen, dtype=torch.float64)
    x_k = torch.randn(4, 16, 2, generator=gen, dtype=torch.float64)
    for k in (99, 50, 1, 0):
        mean, variance = sched.posterior_mean_variance(x0, x_k, k)
        step = sched.ddim_step(x0, x_k, k, k - 1, eta=1.0, noise=torch.zeros_like(x_k))
        torch.testing.assert_close(step, mean, rtol=1e-10, atol=1e-10)
        # sigma^2 of DDIM with eta = 1: shift by unit noise and read the variance back.
        shifted = sched.ddim_step(x0, x_k, k, k - 1, eta=1.0, noise=torch.ones_like(x_k))
        torch.testing.assert_close((shifted - step) ** 2, variance, rtol=1e-10, atol=1e-12)
        if k >= 1:
            abar, abar_prev = sched.alphas_cumprod[k], sched.alphas_cumprod[k - 1]
            beta = sched.betas[k]
            paper = (abar_prev.sqrt() * beta * x0 + sched.alphas[k].sqrt() * (1 - abar_prev) * x_k) / (1 - abar)
            torch.testing.assert_close(mean, paper)
            torch.testing.assert_close(variance, (beta * (1 - abar_prev) / (1 - abar)).expand_as(mean))
    # Step 0 goes to the clean sample.
    torch.testing.assert_close(sched.posterior_mean_variance(x0, x_k, 0)[0], x0)
    torch.testing.assert_close(sched.ddim_step(x0, x_k, 0, -1), x0)


def test_ddim_deterministic_inverts_q_sample() -> None:
    """With eta = 0 and the true x0, a DDIM step lands on q_sample at k_prev with the same noise."""
    sched = cosine_schedule(100)
    x0, noise = torch.randn(3, 5, dtype=torch.float64), torch.randn(3, 5, dtype=torch.float64)
    x_k = sched.q_sample(x0, 80, noise)
    torch.testing.assert_close(sched.ddim_step(x0, x_k, 80, 60), sched.q_sample(x0, 60, noise))


def test_classifier_free_guidance() -> None:
    cond, uncond = torch.tensor([3.0, 1.0]), torch.tensor([1.0, 1.0])
    torch.testing.assert_close(classifier_free_guidance(cond, uncond, -1.0), uncond)
    torch.testing.assert_close(classifier_free_guidance(cond, uncond, 0.0), cond)
    torch.testing.assert_close(classifier_free_guidance(cond, uncond, 1.0), torch.tensor([5.0, 1.0]))


def test_timestep_sequence() -> None:
    assert timestep_sequence(100, num_inference_steps=5) == [99, 79, 59, 39, 19]
    assert timestep_sequence(100, stride=20) == [99, 79, 59, 39, 19]
    assert timestep_sequence(100) == list(range(99, -1, -1))
    assert timestep_sequence(5, stride=1) == [4, 3, 2, 1, 0]
    assert timestep_sequence(100, num_inference_steps=3) == [99, 66, 33]
    with pytest.raises(InputError):
        timestep_sequence(100, stride=2, num_inference_steps=5)
    with pytest.raises(InputError):
        timestep_sequence(100, num_inference_steps=101)


@pytest.mark.parametrize("sampler", ["ddim", "ddpm"])
@pytest.mark.parametrize("eta", [0.0, 1.0])
def test_sampler_with_a_perfect_denoiser(sampler: str, eta: float) -> None:
    sched = cosine_schedule(100)
    target = torch.randn(2, 16, 2, dtype=torch.float64)
    ks = []

    def denoise(x_k: torch.Tensor, k: torch.Tensor) -> torch.Tensor:
        assert x_k.shape == target.shape and k.shape == (2,) and k.dtype == torch.long
        ks.append(int(k[0]))
        return target.clone()

    out = sample(denoise, target.shape, sched, num_inference_steps=10, sampler=sampler, eta=eta, dtype=torch.float64)
    torch.testing.assert_close(out, target)
    assert ks == timestep_sequence(100, num_inference_steps=10)


def test_guidance_hook_called_once_per_step_and_shifts_the_result() -> None:
    sched = cosine_schedule(100)
    calls = []

    def guidance(x0: torch.Tensor, k: torch.Tensor, x_k: torch.Tensor) -> torch.Tensor:
        calls.append((int(k[0]), x0.clone()))
        assert x_k.shape == x0.shape
        return x0 + 1.0

    out = sample(lambda x, k: torch.zeros_like(x), (3, 4), sched, stride=20, guidance=guidance)
    assert [k for k, _ in calls] == [99, 79, 59, 39, 19]
    assert all((x0 == 0).all() for _, x0 in calls)  # it sees the denoiser's x0
    torch.testing.assert_close(out, torch.ones(3, 4))


def test_generator_seeding_is_reproducible() -> None:
    sched = cosine_schedule(100)

    def denoise(x: torch.Tensor, k: torch.Tensor) -> torch.Tensor:
        return 0.5 * x  # depends on the noise, so the output does too

    def run(seed: int, **kwargs) -> torch.Tensor:
        gen = torch.Generator().manual_seed(seed)
        return sample(denoise, (4, 8), sched, stride=10, generator=gen, **kwargs)

    for kwargs in ({"eta": 0.0}, {"eta": 1.0}, {"sampler": "ddpm"}):
        torch.testing.assert_close(run(7, **kwargs), run(7, **kwargs))
        assert not torch.allclose(run(7, **kwargs), run(8, **kwargs))


def test_sampler_rejects_unknown_name() -> None:
    with pytest.raises(InputError):
        sample(lambda x, k: x, (1, 2), cosine_schedule(10), sampler="euler")  # type: ignore[arg-type]
