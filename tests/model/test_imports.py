"""The model package stands on its own: no module under `langtraj.model` loads training, labelling,
plotting or Lightning code (what sampling and simulation deployments import)."""

from __future__ import annotations

import json
import pkgutil
import subprocess
import sys

import langtraj.model

FORBIDDEN = ("langtraj.training", "langtraj.interdrive", "matplotlib", "pytorch_lightning", "lightning")
MODULES = ["langtraj.model"] + [f"langtraj.model.{m.name}" for m in pkgutil.iter_modules(langtraj.model.__path__)]

# In a fresh interpreter, import the modules one by one and record what forbidden packages each brings in.
PROBE = """
import importlib, json, sys
forbidden, modules, found = {forbidden!r}, {modules!r}, {{}}
for module in modules:
    importlib.import_module(module)
    found[module] = sorted(m for m in sys.modules if any(m == p or m.startswith(p + ".") for p in forbidden))
print(json.dumps(found))
"""


def test_no_model_module_imports_training_interdrive_matplotlib_or_lightning():
    assert len(MODULES) > 10  # every module of the package is probed
    probe = PROBE.format(forbidden=FORBIDDEN, modules=MODULES)
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True).stdout
    loaded = {module: names for module, names in json.loads(out).items() if names}
    assert not loaded, f"first offender and what it loads: {next(iter(loaded.items()))}"
