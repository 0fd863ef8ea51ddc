"""How a replan samples (docs/simulation.md). Warm starts (`SimRequest(warm_steps=N)`): the first plan is
the cold one, later replans start from the executed plan and call the network N times instead of `steps`; a
replan between two actions falls back to fresh noise. The temperature scales the noise. With `refresh_map` a
replan reads the map around where the agents are then. Bad settings are one-line errors."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch
from scenario_builders import make_scenario

from langtraj.errors import InputError
from langtraj.model.checkpoint import load_model
from langtraj.sim import LangTrajPolicy, SimConfig, SimRequest, simulate


def _run(model, data, monkeypatch, replan_s: float = 1.0, **kwargs):
    calls = []
    forward = model.denoiser.forward
    monkeypatch.setattr(model.denoiser, "forward", lambda *a, **k: calls.append(1) or forward(*a, **k))
    request = SimRequest(candidates=3, steps=4, selector="min_collision", on_road=0.0, no_collision=0.0, **kwargs)
    policy = LangTrajPolicy(model, data, request)
    rollouts = simulate(make_scenario(5), policy, SimConfig(rollouts=2, replan_s=replan_s, seed=3)).rollouts
    monkeypatch.undo()
    return rollouts, len(calls)


def test_warm_replans_keep_the_first_plan_and_call_the_network_less(tiny_run, monkeypatch):
    model, data = load_model(tiny_run[0])
    cold, cold_calls = _run(model, data, monkeypatch)
    warm, warm_calls = _run(model, data, monkeypatch, warm_steps=2)
    np.testing.assert_allclose(warm.x[..., :10], cold.x[..., :10], atol=1e-5)  # the first second: a cold plan
    assert not np.allclose(warm.x[..., 10:], cold.x[..., 10:], atol=1e-3)
    assert np.isfinite(warm.x).all() and np.isfinite(warm.heading).all()
    assert cold_calls == 8 * 4 and warm_calls == 4 + 7 * 2  # 8 replans; the first cold
    again, _ = _run(model, data, monkeypatch, warm_steps=2)
    np.testing.assert_allclose(again.x, warm.x, atol=1e-6)  # seeded: the same run again


def test_a_replan_between_two_actions_starts_cold(tiny_run, monkeypatch):
    model, data = load_model(tiny_run[0])
    per_action = model.dynamics.steps_per_action
    assert per_action > 1  # so that replanning every 0.1 s falls between actions
    _, calls = _run(model, data, monkeypatch, replan_s=0.1 * (per_action + 1), warm_steps=1)
    replans = -(-80 // (per_action + 1))
    assert calls == replans * 4  # never a whole number of actions since the last plan: every replan is cold


def test_bad_warm_steps_are_refused(tiny_run):
    model, data = load_model(tiny_run[0])
    for bad in (0, 5):
        with pytest.raises(InputError, match="warm-steps"):
            LangTrajPolicy(model, data, SimRequest(steps=4, warm_steps=bad))


def test_the_temperature_scales_the_noise(tiny_run, monkeypatch):
    model, data = load_model(tiny_run[0])
    plain, _ = _run(model, data, monkeypatch)
    same, _ = _run(model, data, monkeypatch, temperature=1.0)
    np.testing.assert_allclose(same.x, plain.x, atol=1e-6)
    seen = []
    sample = model.sample
    monkeypatch.setattr(model, "sample", lambda *a, **k: seen.append(k["noise"]((6, 8, 16, 2))) or sample(*a, **k))
    policy = LangTrajPolicy(model, data, SimRequest(candidates=3, steps=4, temperature=0.5))
    simulate(make_scenario(5), policy, SimConfig(rollouts=2, replan_s=8.0, seed=3))
    policy.request = replace(policy.request, temperature=1.0)
    simulate(make_scenario(5), policy, SimConfig(rollouts=2, replan_s=8.0, seed=3))
    torch.testing.assert_close(seen[0], 0.5 * seen[1])
    for bad in (0.0, -1.0, 3.0, float("nan")):
        with pytest.raises(InputError, match="temperature"):
            LangTrajPolicy(model, data, SimRequest(temperature=bad))


def test_a_refreshed_map_follows_the_agents(tiny_run, monkeypatch):
    model, data = load_model(tiny_run[0])
    maps = []
    encode = model.encoder.forward
    monkeypatch.setattr(
        model.encoder, "forward", lambda b, *a, **k: maps.append(b.map_points.clone()) or encode(b, *a, **k)
    )
    policy = LangTrajPolicy(model, data, SimRequest(candidates=2, steps=2, refresh_map=True))
    scenario = make_scenario(5)
    kept = LangTrajPolicy(model, data, SimRequest(candidates=2, steps=2))
    plain = simulate(scenario, kept, SimConfig(rollouts=2, replan_s=4.0, seed=3)).rollouts
    maps.clear()
    fresh = simulate(scenario, policy, SimConfig(rollouts=2, replan_s=4.0, seed=3)).rollouts
    monkeypatch.undo()
    np.testing.assert_allclose(fresh.x[..., :40], plain.x[..., :40], atol=1e-5)  # the first plan reads the start's map
    assert len(maps) == 2 and maps[1].shape[0] == 2  # the second replan encodes each rollout's own map
    assert not torch.equal(maps[1][0], maps[0][0])  # chosen around where the agents are by then
    assert policy.describe()["refresh_map"] is True
