"""The one angle wrap for numpy and torch, and the inference-time samples (`SampleConfig.for_inference`)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from langtraj.angles import wrap_angle
from langtraj.model.config import SampleConfig


def test_wrap_angle_takes_floats_arrays_and_tensors_in_either_interval() -> None:
    edges = [math.pi, -math.pi, 3 * math.pi, 0.5]
    assert wrap_angle(edges).dtype == np.float64 and wrap_angle(edges).tolist() == [math.pi, math.pi, math.pi, 0.5]
    assert wrap_angle(edges, interval="[-pi, pi)").tolist() == [-math.pi, -math.pi, -math.pi, 0.5]
    for dtype in (torch.float32, torch.float64):
        t = torch.tensor([-10.0, -2.0, 0.5, 3.0, 10.0], dtype=dtype)
        for interval in ("(-pi, pi]", "[-pi, pi)"):
            out = wrap_angle(t, interval=interval)
            assert isinstance(out, torch.Tensor) and out.dtype == dtype
            np.testing.assert_allclose(out.double().numpy(), wrap_angle(t.double().numpy(), interval), atol=1e-6)
    edge = torch.tensor(edges, dtype=torch.float64)
    assert wrap_angle(edge).tolist() == [math.pi, math.pi, math.pi, 0.5]
    assert wrap_angle(edge, interval="[-pi, pi)").tolist() == [-math.pi, -math.pi, -math.pi, 0.5]
    with pytest.raises(ValueError):
        wrap_angle(0.0, interval="[0, 2pi)")  # type: ignore[arg-type]


def test_inference_samples_have_no_dropout() -> None:
    trained = SampleConfig(text_dropout=0.4, history_dropout=0.3, max_agents=24)
    for text in (True, False):
        fed = trained.for_inference(text)
        assert (fed.text, fed.text_dropout, fed.history_dropout, fed.max_agents) == (text, 0.0, 0.0, 24)
    assert trained.for_agents(30).text_dropout == 0.0 and trained.for_agents(30).text is True
