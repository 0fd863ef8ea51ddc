"""Gradient checkpointing (`ModelConfig.gradient_checkpointing`, docs/model.md 'Training memory'): the same
loss and gradients with less kept for backward, nothing changed outside training, and the shipped
checkpoint still loads and gives the outputs it gave before the option existed."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import replace

import pytest
import torch
from batch_builders import toy_batch

from langtraj.model import LangTraj, ModelConfig
from langtraj.model.batch import SceneBatch
from langtraj.model.checkpoint import load_model
from langtraj.sim.checkpoints import shipped_checkpoint

MODEL = ModelConfig(hidden_dim=32, num_heads=4, encoder_layers=2, denoiser_blocks=2, dropout=0.1, use_text=False)


def _twin(model: LangTraj, checkpointing: bool) -> LangTraj:
    """A model with `model`'s weights and gradient checkpointing on or off."""
    twin = LangTraj(replace(model.config, gradient_checkpointing=checkpointing))
    twin.load_state_dict(model.state_dict())
    return twin.train(model.training)


def _loss_and_grads(model: LangTraj, batch: SceneBatch) -> tuple[float, dict[str, torch.Tensor], int]:
    """The training loss at a fixed draw, the gradients, and the bytes saved for backward."""
    saved: dict[int, int] = {}

    def pack(tensor: torch.Tensor) -> torch.Tensor:
        storage = tensor.untyped_storage()
        saved[storage.data_ptr()] = storage.nbytes()
        return tensor

    model.zero_grad()
    torch.manual_seed(5)  # dropout
    with torch.autograd.graph.saved_tensors_hooks(pack, lambda t: t):
        loss = model.loss(batch, generator=torch.Generator().manual_seed(3))["loss"]
    loss.backward()
    grads = {name: p.grad.clone() for name, p in model.named_parameters() if p.grad is not None}
    return float(loss.detach()), grads, sum(saved.values())


def test_checkpointing_gives_the_same_loss_and_gradients_and_keeps_less():
    torch.manual_seed(0)
    plain = LangTraj(MODEL).train()
    batch = toy_batch()
    loss, grads, kept = _loss_and_grads(plain, batch)
    loss_c, grads_c, kept_c = _loss_and_grads(_twin(plain, True), batch)
    assert loss_c == pytest.approx(loss, rel=1e-6)
    assert grads.keys() == grads_c.keys() and len(grads) > 50
    for name, grad in grads.items():
        torch.testing.assert_close(grads_c[name], grad, rtol=1e-5, atol=1e-6, msg=name)
    assert kept_c < kept / 2  # the attention blocks' activations are recomputed, not kept


def test_checkpointing_changes_nothing_outside_training():
    torch.manual_seed(0)
    plain = LangTraj(MODEL).eval()
    checkpointed = _twin(plain, True)
    batch = toy_batch()
    outs = []
    for model in (plain, checkpointed):
        states, _ = model.sample(batch, 2, steps=3, generator=torch.Generator().manual_seed(0))
        outs.append(states)
    torch.testing.assert_close(outs[0], outs[1], rtol=0, atol=0)


@pytest.fixture(scope="module")
def shipped() -> Iterator[LangTraj]:
    """The shipped model, with one torch thread for this module's pinned figures (restored after)."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    model, _ = load_model(shipped_checkpoint())
    yield model
    torch.set_num_threads(threads)


def test_the_shipped_checkpoint_loads_and_gives_the_outputs_it_gave_before(shipped):
    """Pinned with the code before gradient checkpointing existed (the same figures, bit for bit)."""
    assert not shipped.config.gradient_checkpointing
    batch = toy_batch()
    with torch.no_grad():
        scene = shipped.encoder(batch)
        x = torch.randn(2, 6, shipped.config.num_actions, 2, generator=torch.Generator().manual_seed(1))
        out = shipped.denoiser(x, torch.tensor([1, 3]), scene, shipped.language(batch, scene))
        states, _ = shipped.sample(batch, 2, generator=torch.Generator().manual_seed(0))
    before_denoiser = [-0.071392, -0.0527264, -0.271934, -0.217195, 0.18661055, 0.0656118, 0.19007032, -0.0345474]
    before_states = [74.582306, -9.707174, 53.127563, 6.721556, 37.374714, 8.868042]
    assert out[0, :2, :2].flatten().tolist() == pytest.approx(before_denoiser, abs=1e-5)
    assert states[1, 0, :3, -1, :2].flatten().tolist() == pytest.approx(before_states, abs=1e-3)


def test_the_shipped_model_trains_the_same_with_checkpointing(shipped):
    batch = toy_batch()
    plain = _twin(shipped, False).train()
    loss, grads, _ = _loss_and_grads(plain, batch)
    assert loss == pytest.approx(87.458054, rel=1e-5)  # the loss before the option existed
    loss_c, grads_c, _ = _loss_and_grads(_twin(shipped, True).train(), batch)
    assert loss_c == pytest.approx(loss, rel=1e-6)
    for name, grad in grads.items():
        torch.testing.assert_close(grads_c[name], grad, rtol=1e-5, atol=1e-6, msg=name)
