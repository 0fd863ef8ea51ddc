"""Lane-relative inputs (`ModelConfig.lane_inputs`, docs/model.md): each agent's lateral offset and heading
error to its nearest lane, and a network with them that starts as the one without."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest
import torch

from langtraj.model import LangTraj, ModelConfig
from langtraj.model.scene_encoder import LANE_FEATURES, lane_relative_history, lane_steps
from langtraj.scenario.types import MapFeatureType
from tests.batch_builders import toy_batch


def _lane_batch(poses: list[tuple[float, float, float]]):
    """One scene: a lane along +x at y = 0 (and a road edge at y = -3, which is no lane); agents at `poses`
    (x, y, heading) over the whole history."""
    a = len(poses)
    batch = toy_batch(b=1, a=a, m=2, p=10)
    xs = torch.linspace(-50.0, 50.0, 10)
    lane = torch.stack([xs, torch.zeros_like(xs)], -1)
    edge = torch.stack([xs, torch.full_like(xs, -3.0)], -1)
    history = batch.agent_history.clone()
    for i, (x, y, h) in enumerate(poses):
        history[0, i, :, 0:4] = torch.tensor([x, y, math.cos(h), math.sin(h)])
    types = [int(MapFeatureType.LANE_SURFACE_STREET), int(MapFeatureType.ROAD_EDGE_BOUNDARY)]
    return replace(
        batch, agent_history=history, map_points=torch.stack([lane, edge])[None], map_type=torch.tensor([types])
    )


def test_offsets_and_heading_errors_to_the_nearest_lane():
    batch = _lane_batch([(0.0, 1.0, 0.0), (5.0, -1.5, 0.1), (0.0, 30.0, 0.0), (0.0, 0.5, math.pi)])
    features = lane_relative_history(batch)
    assert features.shape == (1, 4, len(lane_steps(11)), LANE_FEATURES)
    first = features[0, :, -1]
    torch.testing.assert_close(first[0], torch.tensor([0.5, 1.0, 0.0, 1.0]))  # 1 m left, aligned
    torch.testing.assert_close(first[1], torch.tensor([-0.75, math.cos(0.1), math.sin(0.1), 1.0]))
    assert (first[2] == 0).all()  # 30 m away: no lane near
    torch.testing.assert_close(first[3], torch.tensor([0.25, -1.0, 0.0, 1.0]), atol=1e-6, rtol=0)  # against it
    invalid = replace(batch, history_valid=torch.zeros_like(batch.history_valid))
    assert (lane_relative_history(invalid) == 0).all()


def test_a_network_with_lane_inputs_starts_as_the_one_without():
    config = ModelConfig(hidden_dim=32, num_heads=4, encoder_layers=1, denoiser_blocks=1, dropout=0.0, use_text=False)
    torch.manual_seed(0)
    plain = LangTraj(config).eval()
    lanes = LangTraj(replace(config, lane_inputs=True)).eval()
    missing, unexpected = lanes.load_state_dict(plain.state_dict(), strict=False)
    assert all(key.startswith("encoder.lane_embed.") for key in missing) and missing and not unexpected
    batch = _lane_batch([(0.0, 1.0, 0.0), (10.0, -1.0, 0.2)])
    with torch.no_grad():
        torch.testing.assert_close(lanes.encoder(batch).agent_tokens, plain.encoder(batch).agent_tokens)
    loss = lanes.loss(batch, generator=torch.Generator().manual_seed(0))["loss"]
    loss.backward()
    assert lanes.encoder.lane_embed[-1].weight.grad.abs().sum() > 0  # it learns from the first step


@pytest.mark.parametrize("lanes", [False, True])
def test_the_setting_round_trips_through_the_config(lanes):
    config = ModelConfig(lane_inputs=lanes)
    assert ModelConfig.from_dict(config.to_dict()).lane_inputs is lanes
