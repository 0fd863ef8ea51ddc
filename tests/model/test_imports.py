"""The model package stands on its own: no module under `langtraj.model` loads training, labelling,
plotting or Lightning code (what sampling and simulation deployments import)."""

from __future__ import annotations

import pkgutil
import subprocess
import sys

import pytest

import langtraj.model

FORBIDDEN = ("langtraj.training", "langtraj.interdrive", "matplotlib", "pytorch_lightning", "lightning")
MODULES = ["langtraj.model"] + [f"langtraj.model.{m.name}" for m in pkgutil.iter_modules(langtraj.model.__path__)]


@pytest.mark.parametrize("module", MODULES)
def test_a_model_module_imports_nothing_above_it(module):
    probe = (
        f"import sys, importlib; importlib.import_module({module!r}); "
        f"print(sorted(m for m in sys.modules if any(m == p or m.startswith(p + '.') for p in {FORBIDDEN!r})))"
    )
    loaded = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True).stdout.strip()
    assert loaded == "[]", f"{module} loads {loaded}"
