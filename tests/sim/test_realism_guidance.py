"""The realism guidance a LangTraj simulation adds by default: which terms, at which denoising steps."""

from __future__ import annotations

import pytest

from langtraj.errors import InputError
from langtraj.guidance import NoCollisionCost, OnRoadCost
from langtraj.guidance.base import FinalSteps
from langtraj.model.checkpoint import load_model
from langtraj.sim.config import SimRequest
from langtraj.sim.policies import DEFAULT_GUIDED_STEPS, LangTrajPolicy


def test_the_realism_guidance_applies_at_the_last_guided_steps(tiny_run):
    model, data = load_model(tiny_run[0])
    on_road, no_collision = LangTrajPolicy(model, data, SimRequest(steps=5, guided_steps=2), free=[2]).realism_terms(4)
    assert isinstance(on_road.cost, OnRoadCost) and isinstance(no_collision.cost, NoCollisionCost)
    assert on_road.schedule == FinalSteps(2, 5) == no_collision.schedule
    assert no_collision.cost.slots == (0, 1, 3) and no_collision.weight == 1.0  # 1 per overlapping pair ...
    assert no_collision.cost.reduction == "sum"  # ... summed, not divided by 3 agents squared
    assert all(
        t.schedule == "all" for t in LangTrajPolicy(model, data, SimRequest(steps=5, guided_steps=5)).realism_terms(4)
    )
    # The default never asks for more steps than the sampler takes.
    assert LangTrajPolicy(model, data, SimRequest(steps=1)).request.guided_steps == 1
    assert (
        LangTrajPolicy(model, data, SimRequest(steps=5)).request.guided_steps == DEFAULT_GUIDED_STEPS == 3
    )  # measured
    with pytest.raises(InputError, match="--guided-steps"):
        LangTrajPolicy(model, data, SimRequest(steps=5, guided_steps=0))
