"""Rolling plans (`model.rolling`, `LangTraj.roll`): the levels roll back onto themselves, a plan whose levels
are all equal reproduces the usual cold start, one call per replan after it, the per-action level input starts
at zero (a model fine-tuned into a rolling one starts where it was), training draws per-action levels."""

from __future__ import annotations

import itertools
from dataclasses import replace

import pytest
import torch
from scenario_builders import make_scenario

from langtraj.errors import InputError
from langtraj.model import LangTraj
from langtraj.model.config import ModelConfig
from langtraj.model.features import collate_scenes, scene_sample
from langtraj.model.rolling import RollingSchedule, denoise_between, shift_plan
from tests.model.test_langtraj import SMALL_DATA as DATA
from tests.model.test_langtraj import SMALL_MODEL

ROLLING = replace(SMALL_MODEL, diffusion_steps=100, rolling_group=2)


@pytest.fixture(scope="module")
def batch():
    return collate_scenes([scene_sample(make_scenario(5, seed=i), DATA) for i in range(2)])


def _noise(seed: int):
    generator = torch.Generator().manual_seed(seed)
    return lambda shape: torch.randn(shape, generator=generator)


def test_levels_rise_along_the_plan_and_a_shift_restores_them():
    schedule = RollingSchedule(num_actions=16, num_steps=100, group=2)
    before, after = schedule.before(), schedule.after()
    assert before.tolist() == [11, 11, 24, 24, 36, 36, 49, 49, 61, 61, 74, 74, 86, 86, 99, 99]
    assert after[:2].tolist() == [-1, -1] and bool((after < before).all())
    shifted = torch.cat([after[2:], torch.full((2,), 99)])  # the plan moved on, fresh noise at the top level
    assert shifted.tolist() == before.tolist()
    calls = schedule.cold_start(5)
    assert calls[0][0].tolist() == [99] * 16 and calls[-1][1].tolist() == after.tolist()
    for (_, target), (levels, _) in itertools.pairwise(calls):
        assert target.tolist() == levels.tolist()  # each call starts where the one before left the plan


def test_training_levels_stay_on_the_schedule_and_rise_along_the_plan():
    schedule = RollingSchedule(num_actions=16, num_steps=100, group=2)
    levels = schedule.training_levels(512, torch.Generator().manual_seed(0))
    assert levels.shape == (512, 16) and int(levels.min()) >= 0 and int(levels.max()) <= 99
    assert bool((levels[:, 1:] >= levels[:, :-1]).all())  # never less noise further ahead
    assert bool((levels[:, 0] < levels[:, -1]).any())


def test_bad_rolling_settings_are_one_line_errors():
    with pytest.raises(InputError, match="rolling_group"):
        ModelConfig(rolling_group=3)
    with pytest.raises(InputError, match="rolling_fraction"):
        ModelConfig(rolling_group=2, rolling_fraction=1.5)
    with pytest.raises(InputError, match="diffusion_steps"):
        RollingSchedule(num_actions=16, num_steps=5, group=2)  # 8 groups need 8 levels
    with pytest.raises(InputError, match="not trained to roll"):
        LangTraj(SMALL_MODEL).roll(None, 1, None, steps=5, noise=_noise(0))  # type: ignore[arg-type]


def test_equal_levels_stay_put_and_a_clean_target_returns_x0():
    schedule = LangTraj(ROLLING).schedule
    x = torch.randn(2, 3, 4, 2, generator=torch.Generator().manual_seed(0))
    predicted = torch.full_like(x, 0.5)
    levels, target = torch.tensor([40, 40, 70, 99]), torch.tensor([-1, 20, 70, 80])
    out, x0 = denoise_between(lambda x_k, k: predicted, x, levels, target, schedule)
    torch.testing.assert_close(x0, predicted)
    torch.testing.assert_close(out[..., 0, :], predicted[..., 0, :])  # clean: the prediction itself
    torch.testing.assert_close(out[..., 2, :], x[..., 2, :])  # same level: untouched
    assert not torch.allclose(out[..., 1, :], x[..., 1, :])
    with pytest.raises(InputError, match="cannot add noise"):
        denoise_between(lambda x_k, k: predicted, x, target, levels, schedule)
    plan = shift_plan(x, 1, torch.zeros_like(x))
    torch.testing.assert_close(plan[..., :3, :], x[..., 1:, :])
    assert bool((plan[..., 3, :] == 0).all())


def test_a_plan_with_equal_levels_reproduces_a_cold_start(batch):
    """One group spanning the plan: every action has the same level at every call, which is the usual sampler."""
    torch.manual_seed(0)
    model = LangTraj(replace(ROLLING, rolling_group=16)).eval()
    _, cold = model.sample(batch, 3, steps=5, noise=_noise(3))
    _, rolled, _ = model.roll(batch, 3, None, steps=5, noise=_noise(3))
    torch.testing.assert_close(rolled, cold, atol=1e-5, rtol=1e-5)


def test_after_the_cold_start_each_replan_is_one_network_call(batch, monkeypatch):
    torch.manual_seed(0)
    model = LangTraj(ROLLING).eval()
    calls = []
    forward = model.denoiser.forward
    monkeypatch.setattr(model.denoiser, "forward", lambda *a, **k: calls.append(a[1]) or forward(*a, **k))
    noise = _noise(1)
    states, actions, plan = model.roll(batch, 3, None, steps=5, noise=noise)
    assert len(calls) == 5 and actions.shape == (3, 2, 8, 16, 2) and plan.shape == (6, 8, 16, 2)
    assert torch.isfinite(states).all()
    calls.clear()
    _, _again, plan2 = model.roll(batch, 3, plan, steps=5, noise=noise)
    assert len(calls) == 1 and calls[0].shape == (6, 16)  # each row reads every action's level
    assert calls[0][0].tolist() == model.rolling.before().tolist()
    assert not torch.equal(plan2, plan)


def test_a_zero_level_input_leaves_a_fine_tuned_model_where_it_started(batch):
    torch.manual_seed(0)
    plain = LangTraj(replace(ROLLING, rolling_group=0)).eval()
    rolling = LangTraj(ROLLING).eval()
    missing = rolling.load_state_dict(plain.state_dict(), strict=False).missing_keys
    assert missing and all(key.startswith("denoiser.level_in") for key in missing)
    _, a = plain.sample(batch, 2, steps=5, noise=_noise(4))
    _, b = rolling.sample(batch, 2, steps=5, noise=_noise(4))
    torch.testing.assert_close(a, b)


def test_training_draws_per_action_levels(batch):
    torch.manual_seed(0)
    model = LangTraj(replace(ROLLING, rolling_fraction=1.0))
    seen = []
    forward = model.denoiser.forward
    model.denoiser.forward = lambda *a, **k: seen.append(a[1]) or forward(*a, **k)  # type: ignore[method-assign]
    out = model.loss(batch, generator=torch.Generator().manual_seed(0), with_states=True)
    assert seen[0].shape == (2, 16) and out["signal"].shape == (2,)
    assert bool((seen[0][:, 0] < seen[0][:, -1]).any())  # rising along the plan, not one level per scene
    out["loss"].backward()
    assert model.denoiser.level_in[-1].weight.grad is not None
