"""Guidance toward a prompt's target moves the closed-loop rollouts of the shipped checkpoint toward it, on a
constructed junction: a stop shortens the prompted car's drive, a right turn turns it right."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from langtraj.guidance.steering import Steering
from langtraj.interdrive.dataset import PromptEntry
from langtraj.interdrive.prompts import parse_user_prompt
from langtraj.model import LangTraj
from langtraj.scenario.types import StateField
from langtraj.sim.config import PromptLevers, SimConfig, SimRequest
from langtraj.sim.engine import simulate
from langtraj.sim.policies import LangTrajPolicy

GUIDANCE_ONLY = PromptLevers(text=False, guidance=True, selection=False)


def _run(loaded, s, text: str | None, levers: PromptLevers = GUIDANCE_ONLY) -> np.ndarray:
    """States [R, A, T, 9] of the simulated 8 s."""
    model, data = loaded
    prompt = None if text is None else PromptEntry.of(parse_user_prompt(text, [1, 2]))
    policy = LangTrajPolicy(model, data, SimRequest(candidates=2, levers=levers, selector="first"), prompt=prompt)
    result = simulate(s, policy, SimConfig(rollouts=2, replan_s=2.0, seed=0))
    return result.world.states[:, :, s.current_index :]


def test_guidance_toward_a_stop_point_shortens_the_prompted_cars_drive(loaded, junction):
    def travelled(states: np.ndarray) -> float:
        xy = states[:, 0, :, [StateField.X, StateField.Y]]
        return float(np.linalg.norm(np.diff(xy, axis=-1), axis=0).sum(-1).mean())

    free, stopped = travelled(_run(loaded, junction, None)), travelled(_run(loaded, junction, "@1 stops"))
    assert stopped < 0.7 * free


def test_guidance_toward_a_right_turn_branch_turns_the_car_right(loaded, junction):
    def heading_change(states: np.ndarray) -> float:
        heading = np.unwrap(states[:, 1, :, StateField.HEADING], axis=-1)
        return float((heading[:, -1] - heading[:, 0]).mean())

    free = heading_change(_run(loaded, junction, None))
    turned = heading_change(_run(loaded, junction, "@2 turns right at the next intersection"))
    assert turned < free - np.radians(30.0)  # right is negative


def test_without_the_text_lever_the_model_sees_no_sentence(loaded, junction):
    from langtraj.sim.world import SimWorld

    model, data = loaded
    prompt = PromptEntry.of(parse_user_prompt("@1 stops", [1, 2]))
    for levers, seen in ((PromptLevers(), True), (GUIDANCE_ONLY, False)):
        policy = LangTrajPolicy(model, data, SimRequest(levers=levers), prompt=prompt)
        world = SimWorld(junction, policy.drives(junction, np.arange(2)), 1)
        sample = policy._sample(world, policy.reset(world, 0), world.start, 0)
        assert (sample["text"][0] is not None) is seen


def test_a_model_with_a_shorter_horizon_is_steered_within_it(loaded, junction, monkeypatch):
    """An 8-action model plans 4 s: its steering terms cover those 4 s (targets later than that are left to
    later replans), not the 8 s of the samples it was trained on."""
    model, data = loaded
    short = LangTraj(replace(model.config, num_actions=8, use_text=False)).eval()
    assert short.horizon_steps == 40
    horizons = []
    terms = Steering.terms
    monkeypatch.setattr(Steering, "terms", lambda self, e, h: horizons.append(h) or terms(self, e, h))
    states = _run((short, data), junction, "@1 stops")
    assert horizons and set(horizons) == {40}
    assert np.isfinite(states[..., StateField.X]).all()


def test_a_prompted_run_warm_starts_with_its_kept_plan_on_offer(loaded, junction, monkeypatch):
    """With every lever and a warm start, the kept plan's actions join the candidates' (one more than sampled),
    so whichever a prompted agent keeps, the next replan starts from what it executed."""
    model, data = loaded
    prompt = PromptEntry.of(parse_user_prompt("@1 stops", [1, 2]))
    policy = LangTrajPolicy(model, data, SimRequest(candidates=2, warm_steps=2), prompt=prompt)
    starts = []
    sample = model.sample
    monkeypatch.setattr(model, "sample", lambda *a, **k: starts.append(k["start"]) or sample(*a, **k))
    result = simulate(junction, policy, SimConfig(rollouts=2, replan_s=1.0, seed=0))
    assert starts[0] is None and all(s is not None for s in starts[1:])  # the first replan is cold
    assert np.isfinite(result.world.states[..., StateField.X]).all()
