"""Local attention: agents of a scene larger than the model's budgets attend to their neighbourhood only,
and within the budgets nothing changes (docs/model.md, 'Local attention')."""

from __future__ import annotations

from dataclasses import replace

import pytest
import torch
from batch_builders import toy_batch
from scenario_builders import make_scenario

from langtraj.errors import InputError
from langtraj.model import LangTraj, ModelConfig
from langtraj.model.checkpoint import load_model
from langtraj.model.config import LocalAttention, SampleConfig
from langtraj.model.features import collate_scenes, scene_sample
from langtraj.model.layers import RelPoseAttention
from langtraj.model.scene_encoder import nearest_neighbours
from langtraj.sim.checkpoints import shipped_checkpoint

DATA = SampleConfig(max_agents=8, max_polylines=12, points_per_polyline=10, text=False, map_selection="origin")
MODEL = ModelConfig(hidden_dim=32, num_heads=4, encoder_layers=1, denoiser_blocks=1, dropout=0.0, use_text=False)


@pytest.fixture(scope="module")
def model() -> LangTraj:
    torch.manual_seed(0)
    return LangTraj(MODEL).eval()


def _batch(agents: int = 7, n: int = 2):
    return collate_scenes([scene_sample(make_scenario(agents, seed=i), DATA) for i in range(n)])


def test_attending_to_every_key_through_an_index_is_dense_attention():
    torch.manual_seed(1)
    attention = RelPoseAttention(16, 4)
    b0, samples, nq, nk = 2, 3, 5, 9
    query = torch.randn(samples * b0, nq, 16, requires_grad=True)
    key = torch.randn(samples * b0, nk, 16)
    query_pose, key_pose = torch.randn(b0, nq, 3), torch.randn(b0, nk, 3)
    mask = torch.rand(samples * b0, nq, nk) > 0.3
    order = torch.stack([torch.randperm(nk) for _ in range(b0 * nq)]).view(b0, nq, nk)  # keys in any order
    dense = attention(
        query,
        query_pose.repeat(samples, 1, 1),
        key,
        key_pose.repeat(samples, 1, 1),
        mask,
        rel=attention.relative(query_pose, key_pose),
    )
    local_mask = torch.gather(mask, -1, order.repeat(samples, 1, 1))
    local = attention(
        query, None, key, None, local_mask, rel=attention.relative(query_pose, key_pose, order), index=order
    )
    assert torch.allclose(dense, local, atol=1e-5)
    (grad_dense,) = torch.autograd.grad(dense.sum(), query)
    (grad_local,) = torch.autograd.grad(local.sum(), query)
    assert torch.allclose(grad_dense, grad_local, atol=1e-5)


def test_fixed_keys_fold_the_context_into_the_pose_terms_without_changing_the_result():
    torch.manual_seed(2)
    from langtraj.model.layers import AttentionBlock

    block = AttentionBlock(16, 4)
    x, context = torch.randn(2, 5, 16), torch.randn(2, 9, 16)
    pose, context_pose = torch.randn(2, 5, 3), torch.randn(2, 9, 3)
    mask = torch.rand(2, 5, 9) > 0.3
    index = torch.stack([torch.randperm(9)[:4] for _ in range(10)]).view(2, 5, 4)
    plain = block(x, pose, context, context_pose, torch.gather(mask, -1, index), index=index)
    fixed = block(
        x,
        pose,
        context,
        context_pose,
        torch.gather(mask, -1, index),
        rel=block.fixed_context(pose, context, context_pose, index),
        index=index,
    )
    assert torch.allclose(plain, fixed, atol=1e-5)


def test_the_neighbours_are_the_nearest_agents_and_map_pieces():
    batch = _batch(agents=7, n=1)
    local = LocalAttention(agents=3, map_pieces=4)
    nb = nearest_neighbours(batch, local)
    real = batch.agent_valid[0].nonzero()[:, 0]
    assert len(real) > 3
    xy = batch.current_state[0, :, :2]
    for agent in real.tolist():
        distances = (xy[real] - xy[agent]).norm(dim=-1)
        assert nb.agents[0, agent, 0] == agent  # itself first
        nearest = real[distances.topk(3, largest=False).indices]
        assert set(nb.agents[0, agent].tolist()) == set(nearest.tolist())
    assert nb.agents_valid[0, real].all()  # more real agents than the budget: every kept one is real
    assert (nb.context[0, :, :3] == nb.agents[0]).all() and (nb.context[0, :, 3:] >= batch.agent_valid.shape[1]).all()
    # An agent with fewer real neighbours than the budget marks the rest invalid.
    sparse = nearest_neighbours(_batch(agents=2, n=1), local)
    assert sparse.agents_valid[0, 0].tolist() == [True, True, False]


def test_a_far_agent_outside_the_neighbourhood_changes_nothing_with_local_attention(model):
    batch = _batch(agents=7)
    local = LocalAttention(agents=3, map_pieces=12)
    xy = batch.current_state[0, :, :2]
    farthest = int(torch.where(batch.agent_valid[0], (xy - xy[0]).norm(dim=-1), -1.0).argmax())
    moved_state = batch.current_state.clone()
    moved_state[0, farthest, :2] += torch.tensor([3.0, -2.0])
    moved = replace(batch, current_state=moved_state)
    still_farthest = (
        torch.where(batch.agent_valid[0], (moved_state[0, :, :2] - xy[0]).norm(dim=-1), -1.0).argmax() == farthest
    )
    assert still_farthest
    x = torch.randn(2, 8, 16, 2, generator=torch.Generator().manual_seed(0))
    k = torch.tensor([10, 60])

    def agent_zero(b, attention):
        scene = model.encoder(b, local=attention)
        return model.denoiser(x, k, scene, model.language(b, scene))[0, 0]

    assert torch.allclose(agent_zero(batch, local), agent_zero(moved, local), atol=1e-6)
    assert not torch.allclose(agent_zero(batch, None), agent_zero(moved, None), atol=1e-6)


def test_within_the_budgets_local_attention_is_dense(model):
    batch = _batch(agents=7)
    dense, _ = model.sample(batch, 2, steps=3, generator=torch.Generator().manual_seed(0))
    local, _ = model.sample(batch, 2, steps=3, generator=torch.Generator().manual_seed(0), local=DATA.local_attention())
    assert model.encoder(batch, local=DATA.local_attention()).neighbours is None
    assert torch.equal(dense, local)
    small, _ = model.sample(
        batch, 2, steps=3, generator=torch.Generator().manual_seed(0), local=LocalAttention(agents=3, map_pieces=5)
    )
    assert small.shape == dense.shape and torch.isfinite(small).all() and not torch.equal(small, dense)


def test_budgets_below_one_are_refused():
    with pytest.raises(InputError, match="local attention agents: must be >= 1"):
        LocalAttention(agents=0, map_pieces=4)


SHIPPED_BEFORE_DENSE = [
    57.995300,
    -10.318781,
    51.541367,
    -5.043102,
    74.988121,
    -26.776720,
    57.435143,
    0.315774,
    45.149536,
    -1.677148,
    66.191040,
    -0.711770,
    63.197838,
    -5.451823,
    44.700264,
    16.988119,
    86.485413,
    -28.378292,
    30.238331,
    2.538637,
    64.730034,
    -4.399478,
    69.386360,
    -3.557725,
    61.695663,
    -10.354245,
    66.110168,
    -8.933033,
    85.008896,
    -29.582489,
    31.227922,
    0.894979,
    51.830505,
    -3.709744,
    86.679993,
    -5.505182,
]
SHIPPED_BEFORE_LOCAL = [
    89.101944,
    -29.324757,
    51.729507,
    -5.746799,
    76.577950,
    -26.444246,
    65.170815,
    0.923383,
    56.664864,
    -2.755396,
    97.746353,
    -0.965754,
    98.156639,
    -5.518046,
    41.203331,
    11.495838,
    91.966385,
    -28.419544,
    46.701202,
    2.085116,
    76.035988,
    -4.928341,
    96.613785,
    -2.971462,
    93.452576,
    -17.474598,
    62.206535,
    -18.477352,
    88.402397,
    -29.454052,
    49.459869,
    -0.230912,
    66.984245,
    -5.202347,
    108.542923,
    -4.978594,
]
"""End positions (every 4th agent) of the shipped checkpoint's samples of a toy batch, dense and local, computed by
the code before the pose-major attention (3245b18): equal bit for bit there and then; pinned here to 1e-4 m so that
another CPU's matrix-product kernels may round differently."""


def test_the_shipped_checkpoint_samples_what_it_sampled_before_the_attention_was_laid_out_anew(one_torch_thread):
    model, _ = load_model(shipped_checkpoint())
    batch = toy_batch(b=2, a=12, m=10)
    for local, before in ((None, SHIPPED_BEFORE_DENSE), (LocalAttention(agents=5, map_pieces=4), SHIPPED_BEFORE_LOCAL)):
        states, _ = model.sample(batch, 3, steps=5, local=local, generator=torch.Generator().manual_seed(0))
        assert states[:, :, ::4, -1, :2].flatten().tolist() == pytest.approx(before, abs=1e-4)
