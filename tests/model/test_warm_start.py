"""Warm-started sampling (`model.diffusion.sample`'s `start`): a start noised to the top step reproduces a cold
start, fewer steps cost fewer network calls and stay nearer the start, bad settings are one-line errors."""

from __future__ import annotations

import pytest
import torch
from scenario_builders import make_scenario

from langtraj.errors import InputError
from langtraj.model import LangTraj
from langtraj.model.diffusion import sample, timestep_sequence
from langtraj.model.features import collate_scenes, scene_sample
from tests.model.test_langtraj import SMALL_DATA as DATA
from tests.model.test_langtraj import SMALL_MODEL as MODEL


@pytest.fixture(scope="module")
def model() -> LangTraj:
    torch.manual_seed(0)
    return LangTraj(MODEL).eval()


@pytest.fixture(scope="module")
def batch():
    return collate_scenes([scene_sample(make_scenario(5, seed=i), DATA) for i in range(2)])


def _sample(model, batch, **kwargs):
    return model.sample(batch, 3, steps=5, generator=torch.Generator().manual_seed(5), **kwargs)


def test_a_warm_start_noised_to_the_last_step_reproduces_a_cold_start(model, batch):
    cold_states, cold = _sample(model, batch)
    zero = torch.zeros(batch.batch_size, 8, model.config.num_actions, 2)
    _, warm = _sample(model, batch, start=zero, start_steps=5)
    torch.testing.assert_close(warm, cold, atol=1e-4, rtol=1e-4)
    plan = torch.randn(zero.shape, generator=torch.Generator().manual_seed(1)) * model.action_scale
    warm_states, warm = _sample(model, batch, start=plan, start_steps=5)
    abar = float(model.schedule.alphas_cumprod[-1])
    assert abar < 1e-4  # the top step keeps almost nothing of the start
    torch.testing.assert_close(warm, cold, atol=0.05 * float(model.action_scale.max()), rtol=0.0)
    assert (warm_states - cold_states)[..., :2].abs().max() < 1.0  # metres, over 8 s


def test_fewer_warm_steps_call_the_network_fewer_times(model, batch, monkeypatch):
    plan = torch.zeros(batch.batch_size, 8, model.config.num_actions, 2)
    calls = []
    forward = model.denoiser.forward
    monkeypatch.setattr(model.denoiser, "forward", lambda *a, **k: calls.append(1) or forward(*a, **k))
    for n in (5, 2, 1):
        calls.clear()
        _sample(model, batch, start=plan, start_steps=n)
        assert len(calls) == n


def test_fewer_warm_steps_stay_nearer_the_start():
    """With a denoiser that trusts its input (x0 = x_k / sqrt(abar_k)), the sample is the start plus the noise
    the first visited step added, sqrt((1 - abar) / abar) of it: less the later the start."""
    schedule = LangTraj(MODEL).schedule
    start = torch.randn(64, 16, 2, generator=torch.Generator().manual_seed(3))

    def trusting(x, k):
        return x / schedule.alphas_cumprod[k].to(x).sqrt()[:, None, None]

    gaps = []
    for n in (1, 2, 3, 4):
        out = sample(trusting, start.shape, schedule, num_inference_steps=5, start=start, start_steps=n,
                     generator=torch.Generator().manual_seed(4))  # fmt: skip
        gaps.append(float((out - start).pow(2).mean().sqrt()))
    first = timestep_sequence(schedule.num_steps, num_inference_steps=5)[-1]
    abar = float(schedule.alphas_cumprod[first])
    assert gaps[0] == pytest.approx(((1 - abar) / abar) ** 0.5, rel=0.1)
    assert gaps == sorted(gaps) and gaps[0] < gaps[-1]


def test_bad_warm_starts_are_one_line_errors(model, batch):
    plan = torch.zeros(batch.batch_size, 8, model.config.num_actions, 2)
    with pytest.raises(InputError, match="start_steps"):
        _sample(model, batch, start=plan, start_steps=6)
    with pytest.raises(InputError, match="start_steps"):
        _sample(model, batch, start=plan)
    with pytest.raises(InputError, match="shape"):
        _sample(model, batch, start=plan[:, :4], start_steps=2)
