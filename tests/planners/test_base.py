"""The planner protocol: loading planners by name or module:Class, duck typing, action kinds and reset calls."""

from __future__ import annotations

import sys
import textwrap

import numpy as np
import pytest

from langtraj.errors import InputError
from langtraj.planners import (
    PLANNERS,
    ConstantVelocityPlanner,
    IDMPlanner,
    LogReplayPlanner,
    Planner,
    load_planner,
    planner_action_kind,
    reset_planner,
)

from .helpers import make_observation

USER_MODULE = """
import numpy as np

from langtraj.planners import Planner


class Braking(Planner):
    def act(self, observation):
        return np.array([-1.0, 0.0], np.float32)


class Duck:
    action_kind = "trajectory"

    def reset(self, observation):
        self.seen = observation

    def act(self, observation):
        return np.zeros((10, 3), np.float32)


class NoAct:
    def reset(self, observation, info):
        pass


class BadKind:
    action_kind = "steering"

    def reset(self, observation, info):
        pass

    def act(self, observation):
        return None


NOT_A_CLASS = 3
"""


@pytest.fixture
def user_module(tmp_path, monkeypatch) -> str:
    """The name of an importable module of user planners."""
    (tmp_path / "user_planners.py").write_text(textwrap.dedent(USER_MODULE))
    (tmp_path / "broken_planners.py").write_text("raise RuntimeError('no GPU\\nsecond line')\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    yield "user_planners"
    for name in ("user_planners", "broken_planners"):
        sys.modules.pop(name, None)


def test_registered_planners_load_by_name():
    assert set(PLANNERS.names()) >= {"idm", "constant_velocity", "log_replay"}
    assert load_planner("idm") is IDMPlanner
    assert load_planner(" constant_velocity ") is ConstantVelocityPlanner
    assert load_planner("log_replay") is LogReplayPlanner


def test_module_class_specs_load_subclasses_and_duck_typed_classes(user_module):
    braking = load_planner(f"{user_module}:Braking")
    assert issubclass(braking, Planner) and planner_action_kind(braking()) == "control"
    duck = load_planner(f"{user_module}:Duck")
    assert not issubclass(duck, Planner) and planner_action_kind(duck()) == "trajectory"
    assert load_planner("langtraj.planners.idm:IDMPlanner") is IDMPlanner


@pytest.mark.parametrize(
    ("spec", "expected"),
    [
        ("no_such_planner", "unknown planner 'no_such_planner'; known: idm"),
        ("no_such_module:Planner", "no module 'no_such_module' (of 'no_such_module:Planner') in the working directory"),
        ("user_planners_x.sub:P", "add that folder to PYTHONPATH"),
        ("broken_planners:X", "cannot import module 'broken_planners' of 'broken_planners:X' (RuntimeError: no GPU)"),
        ("user_planners:Missing", "module 'user_planners' has no 'Missing'"),
        ("user_planners:NoAct", "class 'user_planners:NoAct' has no act method"),
        ("user_planners:NOT_A_CLASS", "'user_planners:NOT_A_CLASS' is not a class"),
        ("user_planners:BadKind", "action_kind 'steering'; expected one of control, trajectory"),
        ("user_planners:", "is neither a planner name nor package.module:Class"),
    ],
)
def test_bad_specs_raise_one_line_input_errors(user_module, spec, expected):
    with pytest.raises(InputError) as caught:
        load_planner(spec)
    message = str(caught.value)
    assert message.startswith("--planner: ") and expected in message and "\n" not in message


def test_a_planner_module_in_the_working_directory_is_found(tmp_path, monkeypatch):
    """`langtraj test --planner mine:Planner` run from the folder of mine.py, as `python -m` would find it; the
    working directory comes after sys.path, so it never shadows an installed package."""
    (tmp_path / "cwd_planners.py").write_text(textwrap.dedent(USER_MODULE))
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(sys, "path", [p for p in sys.path if p not in ("", ".", str(tmp_path))])
    try:
        assert issubclass(load_planner("cwd_planners:Braking"), Planner)
        assert sys.path[-1] == str(tmp_path)
    finally:
        sys.modules.pop("cwd_planners", None)


def test_planner_action_kind_defaults_to_control_and_rejects_others():
    assert planner_action_kind(object()) == "control"
    assert planner_action_kind(LogReplayPlanner()) == "trajectory"

    class Odd:
        action_kind = "torque"

    with pytest.raises(InputError, match="action_kind 'torque'"):
        planner_action_kind(Odd())


def test_reset_planner_passes_the_info_only_to_two_argument_resets():
    obs, info = make_observation(), {"scenario_id": "s", "step_seconds": 0.1}
    calls = []

    class One:
        def reset(self, observation):
            calls.append(("one", observation))

    class Two:
        def reset(self, observation, info):
            calls.append(("two", info))

    class Star:
        def reset(self, *args):
            calls.append(("star", len(args)))

    class Defaulted:
        def reset(self, observation, info=None):
            calls.append(("defaulted", info))

    for planner in (One(), Two(), Star(), Defaulted(), IDMPlanner()):
        reset_planner(planner, obs, info)
    assert calls[0][0] == "one" and calls[0][1] is obs
    assert calls[1:] == [("two", info), ("star", 2), ("defaulted", info)]


def test_the_base_class_defaults():
    planner = load_planner("constant_velocity")()
    planner.reset(make_observation(), {})
    np.testing.assert_array_equal(planner.act(make_observation()), [0.0, 0.0])
    planner.close()
    with pytest.raises(TypeError):
        Planner()  # type: ignore[abstract]
