"""Scene penalties on the predicted trajectory (docs/model.md, 'Scene penalties'): zero on the road and
apart, positive across an edge or in contact, with gradients pointing back; and a training run with them."""

from __future__ import annotations

from dataclasses import replace

import pytest
import torch
from dataset_builders import write_dataset

from langtraj.errors import InputError
from langtraj.scenario.types import AgentType, MapFeatureType
from langtraj.training.config import PenaltyConfig, TrainConfig
from langtraj.training.penalties import contact_penalty, road_penalty, scene_penalties
from langtraj.training.run import train
from tests.batch_builders import toy_batch
from tests.training.test_training import CONFIG, _losses

T = 80


def _road_batch(a: int = 2):
    """One scene: a straight road |y| <= 5 along x (edges keep it on their left), `a` vehicles driving along
    y = 0 at 10 m/s, 20 m apart, the log their future."""
    batch = toy_batch(b=1, a=a, m=2, p=10, f=T)
    xs = torch.linspace(-100.0, 100.0, 10)
    lower = torch.stack([xs, torch.full_like(xs, -5.0)], -1)  # +x: road on its left (y > -5)
    upper = torch.stack([xs.flip(0), torch.full_like(xs, 5.0)], -1)  # -x: road on its left (y < 5)
    t = torch.arange(1, T + 1) * 0.1
    starts = torch.arange(a) * 20.0
    future = torch.zeros(1, a, T, 3)
    future[..., 0] = starts[:, None] + 10.0 * t
    current = torch.zeros(1, a, 4)
    current[..., 0], current[..., 3] = starts, 10.0
    return replace(
        batch,
        map_points=torch.stack([lower, upper])[None],
        map_type=torch.full((1, 2), int(MapFeatureType.ROAD_EDGE_BOUNDARY)),
        agent_type=torch.full((1, a), int(AgentType.VEHICLE)),
        current_state=current,
        future=future,
    )


def _states(batch, dy: float = 0.0) -> torch.Tensor:
    states = torch.cat([batch.future, torch.full((*batch.future.shape[:3], 1), 10.0)], -1).clone()
    states[..., 1] += dy
    return states.requires_grad_(True)


def test_the_road_penalty_is_zero_on_the_road_and_pushes_back_across_an_edge():
    batch = _road_batch()
    assert float(road_penalty(batch, _states(batch), 0.5)) == 0.0
    assert float(road_penalty(batch, _states(batch, dy=4.0), 0.5)) == 0.0  # 1 m inside: beyond the margin
    states = _states(batch, dy=6.0)  # 1 m past the upper edge
    value = road_penalty(batch, states, 0.5)
    assert float(value) == pytest.approx(1.5 - 0.5, rel=1e-3)  # huber(relu(1 - (-0.5))), linear past 1 m
    near = road_penalty(batch, _states(batch, dy=4.75), 0.5)  # 0.25 m inside: 0.25 m too near
    assert float(near) == pytest.approx(0.5 * 0.25**2, rel=1e-3)
    value.backward()
    assert (states.grad[..., 1] > 0).all()  # descent (-grad) moves back toward the road
    assert states.grad[..., 0].abs().max() < 1e-4
    low = _states(batch, dy=-5.5)
    road_penalty(batch, low, 0.5).backward()
    assert (low.grad[..., 1] < 0).all()  # and across the lower edge, upward


def test_the_road_penalty_never_charges_the_log_and_skips_other_agents():
    batch = _road_batch()
    batch = replace(batch, future=batch.future + torch.tensor([0.0, 6.0, 0.0]))  # the log itself is off the road
    assert float(road_penalty(batch, _states(batch), 0.5)) == 0.0  # no further out than the log
    assert float(road_penalty(batch, _states(batch, dy=1.0), 0.5)) == pytest.approx(0.5, rel=1e-3)
    walkers = replace(batch, agent_type=torch.full((1, 2), int(AgentType.PEDESTRIAN)))
    assert float(road_penalty(walkers, _states(batch, dy=1.0), 0.5)) == 0.0
    hidden = replace(batch, future_valid=torch.zeros_like(batch.future_valid))
    assert float(road_penalty(hidden, _states(batch, dy=1.0), 0.5)) == 0.0


def test_the_contact_penalty_is_zero_apart_and_pushes_overlapping_agents_apart():
    batch = _road_batch()
    assert float(contact_penalty(batch, _states(batch))) == 0.0  # 20 m apart
    states = _states(batch).detach().clone()
    states[0, 1, :, :2] = states[0, 0, :, :2] + torch.tensor([0.0, 1.0])  # side by side, 1 m apart: overlap
    states.requires_grad_(True)
    value = contact_penalty(batch, states)
    assert float(value) > 0
    value.backward()
    assert (states.grad[0, 1, :, 1] < 0).all() and (states.grad[0, 0, :, 1] > 0).all()  # descent: apart


def test_scene_penalties_weigh_and_name_their_parts():
    batch = _road_batch()
    states = _states(batch, dy=6.0)
    config = PenaltyConfig(road_weight=2.0, contact_weight=0.5)
    out = scene_penalties(batch, states, config)
    assert set(out) == {"road", "contact", "penalty"}
    assert float(out["penalty"]) == pytest.approx(2.0 * float(out["road"]) + 0.5 * float(out["contact"]))
    half = scene_penalties(batch, states, config, signal=torch.tensor([0.5]))  # a scene weighs its abar_k
    assert float(half["road"]) == pytest.approx(0.5 * float(out["road"]))
    assert float(scene_penalties(batch, states, config, signal=torch.zeros(1))["penalty"]) == 0.0
    assert not PenaltyConfig().active and set(scene_penalties(batch, states, PenaltyConfig())) == {"penalty"}


def test_a_bad_penalty_setting_is_a_one_line_error():
    with pytest.raises(InputError, match=r"penalties\.road_weight"):
        TrainConfig.from_dict({"penalties": {"road_weight": -1.0}})
    with pytest.raises(InputError, match="road_width"):
        TrainConfig.from_dict({"penalties": {"road_width": 1.0}})


def test_a_run_with_scene_penalties_logs_them_beside_the_loss(tmp_path):
    labels = write_dataset(tmp_path / "data", 8)
    config = replace(CONFIG, max_steps=10, penalties=PenaltyConfig(road_weight=1.0, contact_weight=1.0))
    train(config, labels, tmp_path / "run", progress=False)
    rows = (tmp_path / "run" / "logs" / "csv" / "version_0" / "metrics.csv").read_text().splitlines()
    assert {"train/road", "train/contact", "train/penalty"} <= set(rows[0].split(","))
    assert len(_losses(tmp_path / "run")) == 1
