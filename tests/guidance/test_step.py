"""The reconstruction-guidance step: it lowers the cost, steers only its agents, follows its schedule."""

from __future__ import annotations

import pytest
import torch
from scenario_builders import make_scenario

from langtraj.errors import InputError
from langtraj.guidance import (
    CollisionCost,
    GoalCost,
    GuidanceScene,
    GuidanceTerm,
    NoCollisionCost,
    TargetSpeedCost,
    reconstruction_guidance,
)
from langtraj.model import LangTraj, ModelConfig
from langtraj.model.config import SampleConfig
from langtraj.model.dynamics import DYNAMICS
from langtraj.model.features import collate_scenes, scene_sample

from .helpers import displacement_rollout, make_scene

START = torch.tensor([[0.0, 0.0], [0.0, 5.0], [0.0, -5.0]])


def _guide(terms, scene=None, **kwargs):
    scene = scene if scene is not None else make_scene(3)
    return reconstruction_guidance(terms, scene, displacement_rollout(START), num_steps=100, **kwargs)


def _x0(rows: int = 2) -> torch.Tensor:
    return torch.randn(rows, 3, 8, 2, generator=torch.Generator().manual_seed(0)) * 0.5


def test_a_step_lowers_the_cost_and_leaves_unsteered_agents_alone():
    scene = make_scene(3)
    goal = GoalCost(0, (10.0, 3.0))
    rollout = displacement_rollout(START)
    x0 = _x0()
    guided = _guide([GuidanceTerm(goal)], scale=0.5)(x0, torch.tensor([50, 50]), x0)
    assert (goal(rollout(guided), scene) < goal(rollout(x0), scene)).all()
    assert torch.equal(guided[:, 1:], x0[:, 1:])


def test_collision_guidance_moves_the_adversary_only():
    x0 = _x0()
    guided = _guide([GuidanceTerm(CollisionCost(adversary=1, target=0))], scale=0.1)(x0, 10, x0)
    rollout = displacement_rollout(START)
    before, after = rollout(x0), rollout(guided)
    gap = lambda s: (s[:, 1, :, :2] - s[:, 0, :, :2]).norm(dim=-1).mean()  # noqa: E731
    assert gap(after) < gap(before)
    assert torch.equal(guided[:, 0], x0[:, 0]) and torch.equal(guided[:, 2], x0[:, 2])


def test_invalid_agents_are_never_moved():
    scene = make_scene(3, valid=[True, True, False])
    x0 = torch.zeros(1, 3, 8, 2)
    # All three start overlapping; no_collision over all agents may move only the two valid ones.
    start = torch.tensor([[0.0, 0.0], [0.0, 1.0], [0.0, 0.5]])
    guide = reconstruction_guidance(
        [GuidanceTerm(NoCollisionCost())], scene, displacement_rollout(start), num_steps=100, scale=1.0
    )
    guided = guide(x0, 0, x0)
    assert guided[0, :2].abs().sum() > 0
    assert torch.equal(guided[0, 2], x0[0, 2])


def test_the_schedule_picks_the_denoising_steps_per_row():
    x0 = _x0()
    late = _guide([GuidanceTerm(GoalCost(0, (10.0, 3.0)), schedule="late")])
    out = late(x0, torch.tensor([90, 10]), x0)
    assert torch.equal(out[0], x0[0]) and not torch.equal(out[1], x0[1])
    early = _guide([GuidanceTerm(GoalCost(0, (10.0, 3.0)), schedule="early")])
    out = early(x0, torch.tensor([90, 10]), x0)
    assert not torch.equal(out[0], x0[0]) and torch.equal(out[1], x0[1])
    only_zero = _guide([GuidanceTerm(GoalCost(0, (10.0, 3.0)), schedule=lambda k, n: k == 0)])
    assert torch.equal(only_zero(x0, 5, x0), x0) and not torch.equal(only_zero(x0, 0, x0), x0)


def test_weights_clipping_and_iterations():
    x0 = _x0(1)
    goal = GoalCost(0, (30.0, 0.0))
    cost = lambda x: goal(displacement_rollout(START)(x), make_scene(3)).item()  # noqa: E731
    assert torch.equal(_guide([GuidanceTerm(goal, weight=0.0)])(x0, 0, x0), x0)
    clipped = _guide([GuidanceTerm(goal, weight=100.0)], scale=1.0, max_grad_norm=0.25)(x0, 0, x0)
    assert (clipped - x0)[0, 0].norm() == pytest.approx(0.25, rel=1e-4)
    once = _guide([GuidanceTerm(goal)], scale=0.2)(x0, 0, x0)
    thrice = _guide([GuidanceTerm(goal)], scale=0.2, iterations=3)(x0, 0, x0)
    assert cost(thrice) < cost(once) < cost(x0)


def test_guidance_works_inside_no_grad_sampling():
    x0 = _x0()
    with torch.no_grad():
        out = _guide([GuidanceTerm(TargetSpeedCost(0, 2.0))], scale=0.5)(x0, 3, x0)
    assert not out.requires_grad and not torch.equal(out, x0)


def test_bad_step_settings_are_refused():
    for kwargs, message in [
        ({"scale": -1.0}, "scale must be finite and >= 0"),
        ({"iterations": 0}, "iterations must be >= 1"),
        ({"max_grad_norm": 0.0}, "max_grad_norm must be > 0"),
    ]:
        with pytest.raises(InputError, match=message):
            _guide([], **kwargs)
    with pytest.raises(InputError, match="num_steps must be >= 1"):
        reconstruction_guidance([], make_scene(3), displacement_rollout(START), num_steps=0)


def test_guidance_through_the_unicycle_dynamics():
    dynamics = DYNAMICS.create("unicycle")
    initial = torch.tensor([[0.0, 0.0, 0.0, 5.0], [0.0, 10.0, 0.0, 5.0]])
    rollout = lambda x: dynamics(initial.expand(x.shape[0], -1, -1), x)  # noqa: E731
    scene = make_scene(2)
    terms = [GuidanceTerm(GoalCost(0, (35.0, 8.0))), GuidanceTerm(TargetSpeedCost(1, 8.0), weight=0.1)]
    x0 = torch.zeros(1, 2, 16, 2)
    # Yaw-rate gradients have a long lever arm: clipping keeps the steps from overshooting.
    guide = reconstruction_guidance(terms, scene, rollout, num_steps=100, scale=0.1, iterations=20, max_grad_norm=0.5)
    before, after = rollout(x0), rollout(guide(x0, 0, x0))
    assert terms[0].cost(before, scene) > 9.0 and terms[0].cost(after, scene) < 2.0
    assert after[0, 0, -1, 1] > 5.0  # turned left, towards the goal
    assert after[0, 1, :, 3].mean() > before[0, 1, :, 3].mean() + 0.5  # sped up


def test_guided_sampling_with_the_model():
    torch.manual_seed(0)
    config = ModelConfig(hidden_dim=32, num_heads=4, encoder_layers=1, denoiser_blocks=1, dropout=0.0, use_text=False)
    model = LangTraj(config).eval()
    data = SampleConfig(max_agents=4, max_polylines=8, points_per_polyline=10, text=False)
    batch = collate_scenes([scene_sample(make_scenario(3), data)])
    scene = GuidanceScene.from_batch(batch, 0)
    goal = GoalCost(0, (0.0, 20.0))
    num_samples = 2

    def rollout(x: torch.Tensor) -> torch.Tensor:  # one scene: its current state for every candidate
        return model.dynamics(batch.current_state.expand(x.shape[0], -1, -1), model.from_units(x))

    guide = reconstruction_guidance(
        [GuidanceTerm(goal)], scene, rollout, num_steps=model.schedule.num_steps, scale=0.5, iterations=5
    )
    plain, _ = model.sample(batch, num_samples, steps=4, generator=torch.Generator().manual_seed(1))
    guided, _ = model.sample(batch, num_samples, steps=4, guidance=guide, generator=torch.Generator().manual_seed(1))
    assert (goal(guided[:, 0], scene) < goal(plain[:, 0], scene)).all()


def test_one_backward_pass_gives_each_term_its_own_agents_gradient():
    # Reference: each term's gradient on its own, masked to the agents it steers, summed.
    start = torch.tensor([[0.0, 0.0], [0.0, 1.0], [0.0, 2.5]])
    rollout = displacement_rollout(start)
    scene = make_scene(3)
    terms = [
        GuidanceTerm(NoCollisionCost([0, 1], others=[0, 1, 2]), 3.0),
        GuidanceTerm(GoalCost(2, (5.0, 5.0)), 0.5),
        GuidanceTerm(CollisionCost(adversary=1, target=2), 0.2),
    ]
    x0 = _x0()
    x = x0.clone().requires_grad_(True)
    states = rollout(x)
    expected = torch.zeros_like(x0)
    for term in terms:
        (g,) = torch.autograd.grad(term.cost(states, scene).sum() * term.weight, x, retain_graph=True)
        expected += g * term.cost.agents(3)[None, :, None, None]
    guide = reconstruction_guidance(terms, scene, rollout, num_steps=100, scale=1.0)
    assert torch.allclose(x0 - guide(x0, 50, x0), expected, atol=1e-6)


def test_final_steps_are_the_last_timesteps_the_sampler_visits():
    from langtraj.guidance.base import FinalSteps

    k = torch.tensor([99, 79, 59, 39, 19])
    assert FinalSteps(2, 5)(k, 100).tolist() == [False, False, False, True, True]
    assert FinalSteps(5, 5)(k, 100).all()
    assert FinalSteps(1, 10)(torch.arange(100), 100).nonzero()[:, 0].tolist() == [9]  # 99, 89, ..., 9
    with pytest.raises(InputError, match=r"guided steps must be in \[1, 5\], got 6"):
        FinalSteps(6, 5)
