"""Recovery training's perturbations: moving agents' pasts move rigidly sideways and turn, their
futures stay, slow agents stay put, and the fitted targets steer the moved agent back to its path."""

from __future__ import annotations

import math

import torch
from scenario_builders import make_scenario

from langtraj.model import LangTraj, ModelConfig
from langtraj.model.config import SampleConfig
from langtraj.model.features import collate_scenes, scene_sample
from langtraj.training.config import PerturbationConfig
from langtraj.training.perturbation import perturb_pasts

DATA = SampleConfig(max_agents=6, max_polylines=12, points_per_polyline=10, text=False)


def _batch():
    return collate_scenes([scene_sample(make_scenario(5, seed=i), DATA) for i in range(3)])


def test_off_by_default_and_futures_never_move():
    batch = _batch()
    assert perturb_pasts(batch, PerturbationConfig()) is batch
    moved = perturb_pasts(batch, PerturbationConfig(probability=1.0, min_speed=0.0), torch.Generator().manual_seed(0))
    assert torch.equal(moved.future, batch.future) and torch.equal(moved.map_points, batch.map_points)


def test_pasts_move_rigidly_within_the_bounds_and_slow_agents_stay():
    batch = _batch()
    speed = batch.current_state[..., 3]
    min_speed = float(speed[batch.agent_valid].median())
    config = PerturbationConfig(probability=1.0, lateral_m=0.8, heading_rad=0.2, min_speed=min_speed)
    moved = perturb_pasts(batch, config, torch.Generator().manual_seed(1))
    fast = batch.agent_valid & (speed >= min_speed) & batch.future_valid.any(-1)
    slow = batch.agent_valid & ~fast
    assert fast.any() and slow.any()
    assert torch.equal(moved.current_state[slow], batch.current_state[slow])
    assert torch.equal(moved.agent_history[slow], batch.agent_history[slow])
    before, after = batch.current_state[fast], moved.current_state[fast]
    offset = after[:, :2] - before[:, :2]
    heading = torch.stack([torch.cos(before[:, 2]), torch.sin(before[:, 2])], -1)
    assert torch.allclose((offset * heading).sum(-1), torch.zeros(len(offset)), atol=1e-4)  # sideways only
    assert (offset.norm(dim=-1) <= 0.8 + 1e-5).all() and (offset.norm(dim=-1) > 0).all()
    assert ((after[:, 2] - before[:, 2]).abs() <= 0.2 + 1e-6).all()
    # rigid: distances between an agent's valid past points are kept
    valid = batch.history_valid[fast]
    for path, new_path, ok in zip(batch.agent_history[fast], moved.agent_history[fast], valid, strict=True):
        a, b = path[ok, :2], new_path[ok, :2]
        assert torch.allclose(torch.cdist(a, a), torch.cdist(b, b), atol=1e-3)


def test_the_fitted_target_steers_a_moved_car_back_to_its_lane():
    model = LangTraj(ModelConfig(hidden_dim=32, num_heads=4, encoder_layers=1, denoiser_blocks=1, use_text=False))
    batch = _batch()
    agent = (batch.agent_valid[0] & (batch.current_state[0, :, 3] > 1.0)).nonzero()[0, 0]
    # one straight 10 m/s drive along x: the past, the current state and the future
    t = torch.arange(-10, 81, dtype=torch.float32) * 0.1
    history = torch.zeros(11, 7)
    history[:, 0], history[:, 2], history[:, 4], history[:, 6] = 10 * t[:11], 1.0, 10.0, 1.0
    batch.agent_history[0, agent], batch.history_valid[0, agent] = history, True
    batch.current_state[0, agent] = torch.tensor([0.0, 0.0, 0.0, 10.0])
    future = torch.zeros(80, 3)
    future[:, 0] = 10 * t[11:]
    batch.future[0, agent], batch.future_valid[0, agent] = future, True
    config = PerturbationConfig(probability=1.0, lateral_m=1.0, heading_rad=0.0, min_speed=0.0)
    moved = perturb_pasts(batch, config, torch.Generator().manual_seed(0))
    side = float(moved.current_state[0, agent, 1])
    assert abs(side) > 0.2 and float(moved.current_state[0, agent, 2]) == 0.0  # moved sideways, not turned
    x0, _ = model.target_actions(moved)
    yaw = model.from_units(x0)[0, agent, :, 1]
    assert yaw[0] * side < 0 and abs(float(yaw[0])) > 0.02  # turns back towards its lane
    states = model.rollout(moved, x0)[0, agent]
    assert abs(float(states[-1, 1])) < 0.3 and math.isfinite(float(states[-1, 0]))  # back on y = 0
