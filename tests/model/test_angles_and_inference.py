"""The one angle wrap for numpy and torch, and the inference-time samples (`SampleConfig.for_inference`)."""

from __future__ import annotations

import math

import numpy as np
import torch

from langtraj.angles import wrap_angle
from langtraj.model.config import SampleConfig


def test_wrap_angle_takes_floats_arrays_and_tensors() -> None:
    edges = [math.pi, -math.pi, 3 * math.pi, 0.5]
    assert wrap_angle(edges).dtype == np.float64 and wrap_angle(edges).tolist() == [math.pi, math.pi, math.pi, 0.5]
    for dtype in (torch.float32, torch.float64):
        t = torch.tensor([-10.0, -2.0, 0.5, 3.0, 10.0], dtype=dtype)
        out = wrap_angle(t)
        assert isinstance(out, torch.Tensor) and out.dtype == dtype
        np.testing.assert_allclose(out.double().numpy(), wrap_angle(t.double().numpy()), atol=1e-6)
    assert wrap_angle(torch.tensor(edges, dtype=torch.float64)).tolist() == [math.pi, math.pi, math.pi, 0.5]
    grad = torch.tensor([4.0], requires_grad=True)
    wrap_angle(grad).sum().backward()
    assert grad.grad is not None and grad.grad.item() == 1.0  # the graph runs through the wrap


def test_inference_samples_have_no_dropout() -> None:
    trained = SampleConfig(text_dropout=0.4, history_dropout=0.3, max_agents=24)
    for text in (True, False):
        fed = trained.for_inference(text)
        assert (fed.text, fed.text_dropout, fed.history_dropout, fed.max_agents) == (text, 0.0, 0.0, 24)
    assert trained.for_agents(30).text_dropout == 0.0 and trained.for_agents(30).text is True
