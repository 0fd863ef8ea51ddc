"""Rolling plans in closed loop (`SimRequest(rolling=True)`, docs/simulation.md 'Rolling plans'): a cold start,
then one network call per replan; seeded runs repeat; the defaults' guidance and hard constraints apply to every
call; a checkpoint that cannot roll, a replan interval the plan does not roll by and a warm start besides are
one-line errors."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from scenario_builders import make_scenario

from langtraj.errors import InputError
from langtraj.model import LangTraj
from langtraj.sim import LangTrajPolicy, SimConfig, SimRequest, simulate
from tests.model.test_langtraj import SMALL_DATA, SMALL_MODEL
from tests.model.test_rolling import ROLLING


@pytest.fixture(scope="module")
def model() -> LangTraj:
    torch.manual_seed(0)
    return LangTraj(ROLLING).eval()


def _run(model, monkeypatch, replan_s: float = 1.0, **kwargs):
    calls = []
    forward = model.denoiser.forward
    monkeypatch.setattr(model.denoiser, "forward", lambda *a, **k: calls.append(1) or forward(*a, **k))
    policy = LangTrajPolicy(model, SMALL_DATA, SimRequest(candidates=3, steps=4, rolling=True, **kwargs))
    rollouts = simulate(make_scenario(5), policy, SimConfig(rollouts=2, replan_s=replan_s, seed=3)).rollouts
    monkeypatch.undo()
    return rollouts, len(calls)


def test_after_a_cold_start_each_replan_calls_the_network_once(model, monkeypatch):
    paper = {"selector": "min_collision", "on_road": 0.0, "no_collision": 0.0, "hard_constraints": 0}
    rolled, calls = _run(model, monkeypatch, **paper)
    assert calls == 4 + 7  # 8 replans: the cold start's 4 calls, then one each
    assert np.isfinite(rolled.x).all() and np.isfinite(rolled.heading).all()
    again, _ = _run(model, monkeypatch, **paper)
    np.testing.assert_allclose(again.x, rolled.x, atol=1e-6)  # seeded: the same run again


def test_the_defaults_guidance_and_projection_act_at_every_rolling_call(model, monkeypatch):
    seen = []
    from langtraj.guidance import projection

    project = projection.project_states
    monkeypatch.setattr(projection, "project_states", lambda *a, **k: seen.append(1) or project(*a, **k))
    rolled, _ = _run(model, monkeypatch)  # the defaults: on-road and no-collision guidance, hard constraints
    assert len(seen) >= 8 and np.isfinite(rolled.x).all()  # at the cold start's last call, then at every replan


def test_bad_rolling_settings_are_refused(model):
    with pytest.raises(InputError, match="not trained to roll"):
        LangTrajPolicy(LangTraj(SMALL_MODEL), SMALL_DATA, SimRequest(rolling=True))
    with pytest.raises(InputError, match="rolling"):
        LangTrajPolicy(model, SMALL_DATA, SimRequest(steps=4, rolling=True, warm_steps=2))
    policy = LangTrajPolicy(model, SMALL_DATA, SimRequest(candidates=2, steps=4, rolling=True))
    with pytest.raises(InputError, match="replan every 1 s"):
        simulate(make_scenario(5), policy, SimConfig(rollouts=1, replan_s=0.5, seed=0))
