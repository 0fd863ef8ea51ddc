"""Compiled steps (`LangTraj.compile_steps`, a preset's `compile: true`; docs/model.md, 'Fewer, bigger kernels')
compute what eager steps compute, to float rounding, with the weights and their names unchanged."""

from __future__ import annotations

import copy
from dataclasses import replace
from pathlib import Path

import pytest
import torch
from batch_builders import toy_batch

from langtraj.model import LangTraj
from langtraj.model.dynamics import DYNAMICS
from langtraj.model.targets import fit_actions
from langtraj.training.config import load_config
from langtraj.training.module import LangTrajModule

REPO = Path(__file__).resolve().parents[2]


def _stored(batch):
    """The batch with its target actions, as a feature store gives it."""
    dynamics = DYNAMICS.create("unicycle")
    actions, valid = fit_actions(dynamics, batch.current_state, batch.future, batch.future_valid, batch.agent_valid, 16)
    return replace(batch, target_actions=actions, target_valid=valid)


def _step(model: LangTraj, batch) -> tuple[dict[str, float], dict[str, torch.Tensor]]:
    model.zero_grad()
    out = model.loss(batch, generator=torch.Generator().manual_seed(3))
    out["loss"].backward()
    grads = {name: p.grad.clone() for name, p in model.named_parameters() if p.grad is not None}
    return {name: float(value.detach()) for name, value in out.items()}, grads


def test_a_compiled_training_step_gives_the_eager_loss_and_gradients():
    config = load_config(REPO / "configs" / "tiny.yaml")  # dropout 0: the same draws either way
    torch.manual_seed(0)
    eager = LangTraj(config.model).train()
    compiled = copy.deepcopy(eager).compile_steps(sampling=False)
    assert compiled.compiled and not eager.compiled
    assert compiled.state_dict().keys() == eager.state_dict().keys()  # nothing registered by compiling
    batch = _stored(toy_batch(b=3, a=6))
    for _ in range(2):  # the second step runs the compiled graph without compiling
        want, want_grads = _step(eager, batch)
        got, got_grads = _step(compiled, batch)
        assert got == pytest.approx(want, rel=1e-5)
        assert got_grads.keys() == want_grads.keys() and len(got_grads) > 50
        for name, grad in want_grads.items():  # by norm: some gradients are zero but for rounding (key biases)
            error = float((got_grads[name] - grad).norm())
            assert error <= 1e-4 * float(grad.norm()) + 1e-5, (name, error, float(grad.norm()))
        with torch.no_grad():
            for a, b in zip(eager.parameters(), compiled.parameters(), strict=True):
                a.sub_(1e-3 * a.grad)
                b.sub_(1e-3 * b.grad)


def test_a_preset_compiles_its_training_step_only_when_asked():
    config = load_config(REPO / "configs" / "tiny.yaml")
    assert not LangTrajModule(config.to_dict()).model.compiled
    module = LangTrajModule(replace(config, compile=True).to_dict())
    assert module.model.compiled and set(module.model._compiled) == {"loss"}  # validation samples eagerly
    assert load_config(REPO / "configs" / "gpu-short.yaml").compile


@pytest.mark.slow
def test_compiled_sampling_gives_the_eager_samples():
    config = load_config(REPO / "configs" / "tiny.yaml")
    torch.manual_seed(0)
    eager = LangTraj(config.model).eval()
    compiled = copy.deepcopy(eager).compile_steps(training=False)
    batch = toy_batch(b=2, a=6)
    want, _ = eager.sample(batch, 3, steps=5, generator=torch.Generator().manual_seed(0))
    got, _ = compiled.sample(batch, 3, steps=5, generator=torch.Generator().manual_seed(0))
    torch.testing.assert_close(got, want, rtol=1e-4, atol=1e-3)
