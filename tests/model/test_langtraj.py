"""The assembled model: shapes, padding that cannot leak into real agents, loss, sampling, CFG."""

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

# The nearest-origin crop keeps every piece well inside the 50-m map attention radius, whose hard edge
# float rounding could otherwise flip for a pair of pieces at 50 m when the frame test moves the scene.
SMALL_DATA = SampleConfig(max_agents=8, max_polylines=12, points_per_polyline=10, text=False, map_selection="origin")
SMALL_MODEL = ModelConfig(hidden_dim=32, num_heads=4, encoder_layers=1, denoiser_blocks=1, dropout=0.0, use_text=False)


def _batch(n: int = 2, agents: int = 5):
    samples = [scene_sample(make_scenario(agents, seed=i), SMALL_DATA) for i in range(n)]
    return collate_scenes(samples)


@pytest.fixture(scope="module")
def model() -> LangTraj:
    torch.manual_seed(0)
    return LangTraj(SMALL_MODEL).eval()


def test_shapes_of_the_denoiser_and_of_samples(model):
    batch = _batch()
    scene = model.encoder(batch)
    assert scene.agent_tokens.shape == (2, 8, 32) and scene.map_tokens.shape == (2, 12, 32)
    x0, valid = model.target_actions(batch)
    assert x0.shape == (2, 8, 16, 2) and valid.shape == (2, 8, 16)
    out = model.denoiser(x0, torch.tensor([3, 50]), scene, model.language(batch, scene))
    assert out.shape == x0.shape
    states, actions = model.sample(batch, 3, steps=4, generator=torch.Generator().manual_seed(0))
    assert states.shape == (3, 2, 8, 80, 4) and actions.shape == (3, 2, 8, 16, 2)
    assert torch.isfinite(states).all()


def test_padded_agents_and_map_slots_cannot_change_real_agents(model):
    batch = _batch(agents=5)
    pad = ~batch.agent_valid
    assert pad.any()
    noisy = replace(
        batch,
        agent_history=torch.where(
            pad[..., None, None], torch.randn_like(batch.agent_history) * 50, batch.agent_history
        ),
        current_state=torch.where(pad[..., None], torch.randn_like(batch.current_state) * 50, batch.current_state),
        map_points=torch.where(batch.map_valid[..., None], batch.map_points, torch.randn_like(batch.map_points) * 50),
    )
    x = torch.randn(2, 8, 16, 2, generator=torch.Generator().manual_seed(1))
    k = torch.tensor([10, 90])
    outs = []
    for b in (batch, noisy):
        scene = model.encoder(b)
        outs.append(model.denoiser(x, k, scene, model.language(b, scene)))
    valid = batch.agent_valid
    torch.testing.assert_close(outs[0][valid], outs[1][valid], atol=1e-5, rtol=1e-5)
    assert (outs[0][pad] == 0).all()


def test_the_loss_ignores_invalid_future_steps(model):
    batch = _batch()
    torch.manual_seed(3)
    clean = float(model.loss(batch)["position"])
    broken = replace(batch, future=torch.where(batch.future_valid[..., None], batch.future, batch.future + 1e3))
    torch.manual_seed(3)
    assert float(model.loss(broken)["position"]) == pytest.approx(clean, rel=1e-5)


def test_the_model_is_invariant_to_where_the_scene_frame_is(model):
    """Query-centric encoding: rotating and shifting the whole scene moves the sampled states with it."""
    batch = _batch(n=1)
    angle, shift = 0.7, torch.tensor([30.0, -12.0])
    c, s = np.cos(angle), np.sin(angle)
    rot = torch.tensor([[c, -s], [s, c]], dtype=torch.float32)

    def move_xy(xy):
        return xy @ rot.T + shift

    hist = batch.agent_history.clone()
    hist[..., 0:2] = move_xy(hist[..., 0:2])
    hist[..., 2:4] = hist[..., 2:4] @ rot.T
    hist[..., 4:6] = hist[..., 4:6] @ rot.T
    state = batch.current_state.clone()
    state[..., 0:2] = move_xy(state[..., 0:2])
    state[..., 2] += angle
    moved = replace(
        batch,
        agent_history=hist * batch.history_valid[..., None],
        current_state=state,
        map_points=move_xy(batch.map_points) * batch.map_valid[..., None],
    )
    a, _ = model.sample(batch, 1, steps=3, generator=torch.Generator().manual_seed(5))
    b, _ = model.sample(moved, 1, steps=3, generator=torch.Generator().manual_seed(5))
    valid = batch.agent_valid[0]
    torch.testing.assert_close(move_xy(a[0, 0, valid, :, :2]), b[0, 0, valid, :, :2], atol=2e-3, rtol=1e-4)


def test_guidance_weight_minus_one_is_the_unconditional_model():
    torch.manual_seed(0)
    config = replace(SMALL_MODEL, use_text=True)
    model = LangTraj(config).eval()
    data = replace(SMALL_DATA, text=True)
    batch = collate_scenes([scene_sample(make_scenario(5), data)])
    batch = replace(batch, text=[["the target agent turns left"] + [None] * 7])
    no_text = replace(batch, text=[[None] * 8])
    gen = torch.Generator()
    uncond, _ = model.sample(batch, 1, steps=3, guidance_weight=-1.0, generator=gen.manual_seed(2))
    plain, _ = model.sample(no_text, 1, steps=3, generator=gen.manual_seed(2))
    cond, _ = model.sample(batch, 1, steps=3, generator=gen.manual_seed(2))
    torch.testing.assert_close(uncond, plain)
    assert not torch.allclose(cond, plain)


def _text_model_and_batch():
    torch.manual_seed(0)
    model = LangTraj(replace(SMALL_MODEL, use_text=True)).eval()
    batch = collate_scenes([scene_sample(make_scenario(5), replace(SMALL_DATA, text=True))])
    return model, replace(batch, text=[["the target agent turns left"] + [None] * 7])


def test_text_weight_counts_the_agents_with_a_sentence_more():
    model, batch = _text_model_and_batch()
    off = batch.future.clone()
    off[0, 0, :, :2] += 5.0  # only the agent with a sentence is off its log
    broken = replace(batch, future=off)
    increase = {}
    for weight in (1.0, 5.0):
        losses = []
        for b in (batch, broken):
            torch.manual_seed(4)
            losses.append(float(model.loss(b, text_weight=weight)["position"]))
        increase[weight] = losses[1] - losses[0]
    assert increase[5.0] > 2.0 * increase[1.0] > 0.0
    no_text = replace(batch, text=[[None] * 8])
    torch.manual_seed(4)
    plain = float(model.loss(no_text)["loss"])
    torch.manual_seed(4)
    assert float(model.loss(no_text, text_weight=5.0)["loss"]) == pytest.approx(plain)


def test_samples_share_the_scene_without_changing_the_result(model):
    """Pose terms computed once per scene (sample-major sharing) give what per-row terms give."""
    from langtraj.model.diffusion import sample
    from langtraj.model.langtraj import _repeat_batch

    batch = _batch(n=2)
    shared, _ = model.sample(batch, 3, steps=4, generator=torch.Generator().manual_seed(5))
    repeated = _repeat_batch(batch, 3)
    scene = model.encoder(repeated)
    language = model.language(repeated, scene)
    x0 = sample(
        lambda x, k: model.denoiser(x, k, scene, language),  # no cache: pose terms per row
        (6, 8, 16, 2),
        model.schedule,
        num_inference_steps=4,
        generator=torch.Generator().manual_seed(5),
    )
    per_row = model.rollout(repeated, x0).reshape(3, 2, 8, 80, 4)
    torch.testing.assert_close(shared, per_row, atol=1e-3, rtol=1e-4)


def test_a_kept_map_encoding_gives_the_same_samples(model):
    batch = _batch(n=3)  # one map for all three scenes: the same scene with other agents' noise
    shared = replace(batch, map_points=batch.map_points[:1].expand_as(batch.map_points).clone(),
                     map_valid=batch.map_valid[:1].expand_as(batch.map_valid).clone(),
                     map_type=batch.map_type[:1].expand_as(batch.map_type).clone())  # fmt: skip
    one = replace(
        shared, map_points=shared.map_points[:1], map_valid=shared.map_valid[:1], map_type=shared.map_type[:1]
    )
    with torch.no_grad():
        kept = model.encoder.encode_map(one)
    plain, _ = model.sample(shared, 2, steps=3, generator=torch.Generator().manual_seed(4))
    cached, _ = model.sample(shared, 2, steps=3, generator=torch.Generator().manual_seed(4), map_context=kept)
    torch.testing.assert_close(cached, plain, atol=1e-5, rtol=1e-5)


def test_a_long_vehicle_turns_wider_than_a_car_and_a_pedestrian_is_not_bounded(model):
    # A 12 m bus, a 4.5 m car (both vehicles) and a pedestrian, each at 8 m/s, asked the same hard yaw rate.
    types = torch.tensor([[1, 1, 2]])  # AgentType: vehicle, vehicle, pedestrian
    lengths = torch.tensor([[12.0, 4.5, 0.6]])
    bound = model.max_curvature(types, lengths)
    assert bound[0, 0] == pytest.approx(1 / (SMALL_MODEL.turn_radius_per_length * 12.0))  # a 9.6 m radius
    assert bound[0, 1] == pytest.approx(SMALL_MODEL.vehicle_max_curvature)  # a car keeps the flat 4 m bound
    assert torch.isinf(bound[0, 2])
    flat = ModelConfig(turn_radius_per_length=0.0).vehicle_curvature(lengths)
    assert torch.equal(flat, torch.full((1, 3), 0.25))  # 0: the flat bound alone
    current = torch.tensor([[[0.0, 0.0, 0.0, 8.0]] * 3])
    x0 = model.to_units(torch.tensor([0.0, 3.0]).expand(1, 3, 16, 2))
    heading = model.integrate(current, types, lengths, x0)[0, :, 9, 2]  # after 1 s
    assert heading[0] == pytest.approx(8.0 / 9.6, rel=1e-4) and heading[1] == pytest.approx(8.0 * 0.25, rel=1e-4)
    assert heading[2] == pytest.approx(3.0, rel=1e-4)  # the yaw rate asked, unbounded
    with pytest.raises(InputError, match="turn_radius_per_length"):
        ModelConfig(turn_radius_per_length=-1.0)
