"""The package layering of docs/design.md, 'Package layout': imports only point downward, no two modules import
each other (not even for type hints), and the simulation loads neither the SUMO factory nor the renderer."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src" / "langtraj"

LAYERS = (
    ("errors",),
    ("angles", "frames", "polylines", "fileio", "registry", "settings"),
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
APART = {"sim": {"synth", "viz", "labeling"}}
"""Lower packages a package never imports, not even lazily: the simulation engine needs no SUMO factory, renderer
or labeling tool (what the model may load: tests/model/test_imports.py)."""


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


def _module_level_imports(path: Path, modules: set[str]) -> set[str]:
    """The langtraj modules a file imports outside its functions (`if TYPE_CHECKING:` blocks included): the
    imports that tie modules together; an import inside a function is a deliberate lazy one."""
    found: set[str] = set()

    def visit(statements: list[ast.stmt]) -> None:
        for node in statements:
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("langtraj"):
                for alias in node.names:  # `from package import submodule` imports the submodule
                    submodule = f"{node.module}.{alias.name}"
                    found.add(submodule if submodule in modules else node.module)
            elif isinstance(node, ast.Import):
                found.update(alias.name for alias in node.names if alias.name.startswith("langtraj"))
            elif isinstance(node, ast.If | ast.Try | ast.With):
                for block in ("body", "orelse", "finalbody", "handlers"):
                    visit([s for s in getattr(node, block, []) if isinstance(s, ast.stmt)])
                for handler in getattr(node, "handlers", []):
                    visit(handler.body)

    visit(ast.parse(path.read_text()).body)
    return found


def test_no_two_modules_import_each_other():
    modules = {}
    for path in SRC.rglob("*.py"):
        name = ".".join(path.relative_to(SRC.parent).with_suffix("").parts).removesuffix(".__init__")
        modules[name] = path
    names = set(modules)
    graph = {m: {t for t in _module_level_imports(p, names) if t in names and t != m} for m, p in modules.items()}
    cycles = []
    state: dict[str, int] = {}  # 1: on the current path, 2: done

    def walk(module: str, path: list[str]) -> None:
        state[module] = 1
        for target in sorted(graph[module]):
            if state.get(target) == 1:
                cycles.append(" -> ".join([*path[path.index(target) :], target]))
            elif target not in state:
                walk(target, [*path, target])
        state[module] = 2

    for module in sorted(graph):
        if module not in state:
            walk(module, [module])
    assert not cycles, "\n".join(cycles)


def test_the_engine_keeps_apart_from_what_it_does_not_need():
    found = [
        f"{path.relative_to(SRC)} imports langtraj.{imported}"
        for path in sorted(SRC.rglob("*.py"))
        for imported in _imported_packages(path) & APART.get(_top_package(path), set())
    ]
    assert not found, "\n".join(found)


def test_the_simulation_loads_neither_the_factory_nor_the_renderer():
    code = (
        "import sys, langtraj.sim; "
        "print(sorted(m for m in sys.modules if m.startswith(('langtraj.synth', 'langtraj.viz'))))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
