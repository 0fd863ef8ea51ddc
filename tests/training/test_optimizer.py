"""The optimizer and clipping training configures (docs/model.md, 'Fewer, bigger kernels'): fused AdamW unless a
gradient scaler is in play, clipped by norm before its step."""

from __future__ import annotations

import pytest
import torch

from langtraj.errors import InputError
from langtraj.model import ModelConfig
from langtraj.training.config import TrainConfig
from langtraj.training.module import LangTrajModule, is_fused

MODEL = ModelConfig(hidden_dim=16, num_heads=2, encoder_layers=1, denoiser_blocks=1, use_text=False)


def module_for(precision: str) -> LangTrajModule:
    return LangTrajModule(TrainConfig(name="opt", model=MODEL, precision=precision).to_dict())


@pytest.mark.parametrize(
    ("precision", "fused"), [("32-true", True), ("bf16-mixed", True), ("16-mixed", False), ("16", False)]
)
def test_fused_unless_the_loss_is_scaled(precision, fused):
    assert is_fused(module_for(precision).configure_optimizers()["optimizer"]) == fused


def test_a_fused_optimizer_is_clipped_by_norm_here():
    module = module_for("bf16-mixed")
    optimizer = module.configure_optimizers()["optimizer"]
    params = [p for group in optimizer.param_groups for p in group["params"]]
    for p in params:
        p.grad = torch.full_like(p, 3.0)
    module.configure_gradient_clipping(optimizer, gradient_clip_val=0.5, gradient_clip_algorithm="norm")
    total = torch.linalg.vector_norm(torch.stack([torch.linalg.vector_norm(p.grad) for p in params]))
    assert total == pytest.approx(0.5, rel=1e-4)
    module.configure_gradient_clipping(optimizer, gradient_clip_val=None)  # no clipping asked: gradients kept
    assert torch.linalg.vector_norm(torch.stack([torch.linalg.vector_norm(p.grad) for p in params])) == total
    with pytest.raises(InputError, match="'value'"):
        module.configure_gradient_clipping(optimizer, gradient_clip_val=0.5, gradient_clip_algorithm="value")
