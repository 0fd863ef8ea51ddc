"""The package layering of docs/design.md, 'Package layout': imports only point downward, and the simulation
loads neither the SUMO factory nor the renderer."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src" / "langtraj"

LAYERS = (
    ("errors",),
    ("angles", "frames", "fileio", "registry", "settings"),
    ("executors", "runs"),
    ("scenario",),
    ("rollouts", "viz", "synth", "interdrive"),
    ("metrics", "model"),
    ("guidance",),
    ("sim",),
    ("training", "labeling"),
    ("experiments",),
    ("cli",),
)
"""Each package may import only packages of earlier layers (and itself)."""
RANK = {package: rank for rank, layer in enumerate(LAYERS) for package in layer}


def _top_package(path: Path) -> str:
    return path.relative_to(SRC).parts[0].removesuffix(".py")


def _imported_packages(path: Path) -> set[str]:
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        names = []
        if isinstance(node, ast.ImportFrom) and node.module:
            names = [node.module]
        elif isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        found |= {n.split(".")[1] for n in names if n.startswith("langtraj.") and n.count(".") >= 1}
    return found


def test_every_package_has_a_layer():
    packages = {_top_package(p) for p in SRC.rglob("*.py")} - {"__init__", "__main__", "_version"}
    assert packages <= set(RANK), f"give these a layer in LAYERS: {sorted(packages - set(RANK))}"


def test_imports_only_point_downward():
    upward = []
    for path in sorted(SRC.rglob("*.py")):
        package = _top_package(path)
        if package not in RANK:
            continue
        for imported in _imported_packages(path) - {package}:
            if imported in RANK and RANK[imported] >= RANK[package]:
                upward.append(f"{path.relative_to(SRC)} imports langtraj.{imported}")
    assert not upward, "\n".join(upward)


def test_the_simulation_loads_neither_the_factory_nor_the_renderer():
    code = (
        "import sys, langtraj.sim; "
        "print(sorted(m for m in sys.modules if m.startswith(('langtraj.synth', 'langtraj.viz'))))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
