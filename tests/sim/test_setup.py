"""`build_policy` refuses what no policy can simulate before it loads anything: here, a scene without the history
the model reads."""

from __future__ import annotations

from dataclasses import replace

import pytest
from scenario_builders import make_scenario

from langtraj.errors import InputError
from langtraj.sim.config import SimRequest
from langtraj.sim.setup import build_policy


def test_a_scene_without_the_models_history_is_refused_in_one_line():
    short = replace(make_scenario(), current_index=3)
    with pytest.raises(InputError) as raised:
        build_policy(short, SimRequest())  # refused before the checkpoint is loaded
    assert str(raised.value).startswith(
        "scenario: scenario toy has 3 step(s) before its current step; the model reads 10"
    )
    policy, _ = build_policy(short, SimRequest(policy="constant_velocity"))  # a policy without a model may run it
    assert policy is not None
