"""The suites' `FakeEnv` stands in for `LangTrajEnv` only while it keeps the real one's interface: a parameter the
real environment renames, drops or gives another default would otherwise pass the suite tests and fail users."""

from __future__ import annotations

import inspect

import pytest

from langtraj.env import LangTrajEnv
from suites.fakes import FakeEnv


@pytest.mark.parametrize("method", ["__init__", "reset", "step", "close"])
def test_every_parameter_of_the_fake_is_the_real_environments_with_its_kind_and_default(method):
    fake = inspect.signature(getattr(FakeEnv, method)).parameters
    real = inspect.signature(getattr(LangTrajEnv, method)).parameters
    for name, parameter in fake.items():
        assert name in real, f"FakeEnv.{method} takes {name!r}; LangTrajEnv.{method} does not"
        assert parameter.kind == real[name].kind, f"{method}({name}): positional or keyword differs"
        if parameter.default is not inspect.Parameter.empty:  # the fake may require what a suite always gives
            assert parameter.default == real[name].default, f"{method}({name}): default differs"
    required = [n for n, p in real.items() if p.default is inspect.Parameter.empty and p.kind in (p.KEYWORD_ONLY,)]
    assert set(required) <= set(fake), f"LangTrajEnv.{method} requires {required}; the fake must take them"


def test_the_fake_offers_what_a_suite_reads_of_the_environment():
    """A suite reads `highlight_ids` (set at reset) and `played()` besides the Gymnasium calls."""
    assert "self.highlight_ids =" in inspect.getsource(LangTrajEnv)
    assert "self.highlight_ids =" in inspect.getsource(FakeEnv)
    played = inspect.signature(LangTrajEnv.played).parameters
    assert inspect.signature(FakeEnv.played).parameters.keys() == played.keys()
