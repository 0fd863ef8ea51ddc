"""Closed-loop training (Algorithm 1) on constructed cases: teacher-forced agents follow the ground
truth, the executed candidate is the closest one, and the loss reaches exactly that candidate's
denoiser output; a closed-loop stage trains and resumes like the others."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch
from scenario_builders import make_scenario

from langtraj.errors import InputError
from langtraj.model import LangTraj, ModelConfig
from langtraj.model.config import SampleConfig
from langtraj.model.features import collate_scenes, scene_sample
from langtraj.training.closed_loop import closed_loop_loss, forced_agents, select_closest
from langtraj.training.config import ClosedLoopConfig, TrainConfig

DATA = SampleConfig(max_agents=6, max_polylines=12, points_per_polyline=10, text=False)
MODEL = ModelConfig(
    hidden_dim=32, num_heads=4, encoder_layers=1, denoiser_blocks=1, dropout=0.0, use_text=False,
    num_actions=8, diffusion_steps=5,
)  # fmt: skip


def _batch(n: int = 3):
    return collate_scenes([scene_sample(make_scenario(5, seed=i), DATA) for i in range(n)])


@pytest.fixture()
def model() -> LangTraj:
    torch.manual_seed(0)
    return LangTraj(MODEL)


def test_select_closest_picks_the_candidate_nearest_the_ground_truth():
    target = torch.zeros(2, 3, 4, 2)
    states = torch.stack([torch.full((2, 3, 4, 2), d) for d in (3.0, 0.5, 1.0)])  # [M=3, B, A, T, 2]
    states[2, 1] = 0.1  # scene 1: candidate 2 is nearest
    valid = torch.ones(2, 3, 4, dtype=torch.bool)
    assert select_closest(states, target, valid).tolist() == [1, 2]
    valid[1, :, :] = False  # nothing to compare: any candidate, deterministically the first
    valid[1, 0, 0] = True
    states[0, 1, 0, 0] = 0.0
    assert select_closest(states, target, valid).tolist() == [1, 0]


def test_teacher_forced_agents_follow_the_ground_truth_and_carry_no_loss(model):
    batch = _batch()
    config = ClosedLoopConfig(teacher_forcing=1.0, forced_agents=1.0, collision_weight=0.0)
    out = closed_loop_loss(model, batch, config, generator=torch.Generator().manual_seed(0))
    assert float(out["forced"]) == pytest.approx(1.0)
    assert float(out["position"]) == 0.0  # every agent forced: nothing is scored
    # and what they executed is the ground truth: the world they hand the next replan
    executed = []
    original = batch.advanced

    def record(self, steps):
        executed.append(steps)
        return original.__func__(self, steps)

    type(batch).advanced = record
    try:
        closed_loop_loss(model, batch, config, generator=torch.Generator().manual_seed(0))
    finally:
        type(batch).advanced = original.__func__
    path = torch.cat(executed, dim=2)
    steps = path.shape[2]
    valid = batch.future_valid[:, :, :steps] & batch.agent_valid[..., None]
    err = torch.linalg.vector_norm(path[..., :2] - batch.future[:, :, :steps, :2], dim=-1)[valid]
    assert float(err.max()) < 0.05


def test_the_executed_candidate_is_the_closest_and_the_loss_reaches_its_denoiser_output(model):
    batch = _batch()
    config = ClosedLoopConfig(teacher_forcing=0.0, candidates=4, collision_weight=0.0, iterations=2)
    calls = []
    forward = model.denoiser.forward

    def keep(*args, **kwargs):
        out = forward(*args, **kwargs)
        if out.requires_grad:
            out.retain_grad()
        calls.append(out)
        return out

    model.denoiser.forward = keep
    out = closed_loop_loss(model, batch, config, generator=torch.Generator().manual_seed(1))
    out["loss"].backward()
    assert float(out["loss"]) > 0
    assert any(p.grad is not None and p.grad.abs().sum() > 0 for p in model.denoiser.parameters())
    b, horizon = batch.batch_size, model.horizon_steps
    start = batch
    for it in range(2):
        candidates, executed = calls[2 * it], calls[2 * it + 1]
        assert not candidates.requires_grad and executed.grad is not None and executed.grad.abs().sum() > 0
        values = candidates.reshape(4, b, *candidates.shape[1:])
        states = model.integrate(
            start.current_state.repeat(4, 1, 1),
            start.agent_type.repeat(4, 1),
            start.agent_size[..., 0].repeat(4, 1),
            candidates,
        )
        states = states.reshape(4, b, *states.shape[1:]).detach()
        valid = start.future_valid[:, :, :horizon] & start.agent_valid[..., None]
        err = torch.linalg.vector_norm(states[..., :2] - start.future[None, :, :, :horizon, :2], dim=-1)
        mean = (err * valid).sum(dim=(2, 3)) / valid.sum(dim=(1, 2)).clamp(min=1)
        for scene in range(b):
            nearest = int(mean[:, scene].argmin())
            torch.testing.assert_close(executed[scene].detach(), values[nearest, scene], atol=1e-5, rtol=1e-5)
        steps = model.integrate(start.current_state, start.agent_type, start.agent_size[..., 0], executed.detach())[
            :, :, :10
        ]
        start = start.advanced(steps)


def test_forcing_draws_whole_scenes_then_agents():
    batch = _batch(64)
    config = ClosedLoopConfig(teacher_forcing=0.5, forced_agents=0.7)
    forced = forced_agents(batch, config, torch.Generator().manual_seed(0))
    scenes = forced.any(dim=1).float().mean()
    share = forced[forced.any(dim=1)].float().sum() / batch.agent_valid[forced.any(dim=1)].sum()
    assert 0.3 < float(scenes) < 0.7 and 0.5 < float(share) < 0.9
    assert not (forced & ~batch.agent_valid).any()


def test_the_horizon_must_fit_the_logged_future():
    val = replace(TrainConfig().val, sample_steps=5, wosac_scenes=0)
    with pytest.raises(InputError, match="need 14 logged actions; samples hold 10"):
        TrainConfig(objective="closed_loop", model=MODEL, data=replace(DATA, future_steps=50), val=val)
    with pytest.raises(InputError, match="10 sampling steps for a 5-step model"):
        TrainConfig(objective="closed_loop", model=MODEL, data=DATA)
    with pytest.raises(InputError, match="this model plans 4 s"):
        TrainConfig(objective="closed_loop", model=MODEL, data=DATA, val=replace(val, wosac_scenes=1))
    TrainConfig(objective="closed_loop", model=MODEL, data=DATA, val=val)


def test_a_shorter_horizon_starts_from_the_first_actions_weights():
    from langtraj.training.run import _leading_slice

    weight = torch.arange(12.0).reshape(2, 6)  # 3 actions x 2 channels per row
    assert _leading_slice(weight, torch.Size([2, 4])).tolist() == [[0, 1, 2, 3], [6, 7, 8, 9]]
    assert _leading_slice(weight, torch.Size([3, 4])) is None
    assert np.array_equal(_leading_slice(torch.arange(6.0), torch.Size([4])).numpy(), np.arange(4.0))


def test_the_denoising_loss_can_join_the_closed_loop_loss():
    from langtraj.training.module import LangTrajModule

    val = replace(TrainConfig().val, sample_steps=5, wosac_scenes=0)
    with pytest.raises(InputError, match=r"closed_loop\.denoising_weight: must be >= 0"):
        ClosedLoopConfig(denoising_weight=-1.0)
    config = TrainConfig(
        objective="closed_loop", model=MODEL, data=DATA, val=val,
        closed_loop=ClosedLoopConfig(candidates=2, iterations=1, denoising_weight=2.0, collision_weight=0.0),
    )  # fmt: skip
    module = LangTrajModule(config.to_dict())
    torch.manual_seed(0)
    out = module.objective(_batch())
    torch.manual_seed(0)
    plain = closed_loop_loss(module.model, _batch(), config.closed_loop)
    torch.testing.assert_close(out["loss"], plain["loss"] + 2.0 * out["denoising"])
