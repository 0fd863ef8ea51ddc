"""The package layering of docs/design.md, 'Import rules': imports only point downward, no two modules import
each other (not even for type hints), and the simulation loads neither the SUMO factory nor the renderer. Every
rule holds for imports at any level: inside functions and methods (lazy imports), `if TYPE_CHECKING:` blocks and
module level alike. The only imports a rule leaves to functions are third-party heavy ones: Ray and libsumo only
inside the functions that use them, torch from the model's layer upward (below it, for type hints only)."""

from __future__ import annotations

import ast
import re
import subprocess
import sys
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src" / "langtraj"

LAYERS = (
    ("errors",),
    ("angles", "car_following", "frames", "polylines", "fileio", "registry", "settings", "web"),
    ("executors", "runs"),
    ("scenario",),
    ("roads",),
    ("rollouts", "viz", "synth", "interdrive"),
    ("metrics", "model"),
    ("guidance",),
    ("sim",),
    ("cases",),
    ("training", "labeling", "env"),
    ("planners",),
    ("suites", "experiments"),
    ("studio",),
    ("cli",),
)
"""Each package may import only packages of earlier layers (and itself)."""
RANK = {package: rank for rank, layer in enumerate(LAYERS) for package in layer}
APART = {"sim": {"synth", "viz", "labeling"}, "env": {"interdrive"}}
"""Lower packages a package never imports, not even lazily: the simulation engine needs no SUMO factory, renderer
or labeling tool (what the model may load: tests/model/test_imports.py); the env reads the road from `roads`, not
from the labels package."""


def _top_package(path: Path) -> str:
    return path.relative_to(SRC).parts[0].removesuffix(".py")


LAZY_ONLY = ("ray", "libsumo")
"""Third-party packages imported only inside the functions that use them (docs/design.md, 'Import rules')."""
TORCH_FROM = "model"
"""torch is imported from this package's layer upward; below it only for type hints (`angles` wraps tensors
without importing torch)."""


def _imports(path: Path) -> list[tuple[str, tuple[str, ...], str]]:
    """(module, names, place) of every absolute import in a file: `import a.b` gives ("a.b", (), place), `from a
    import b, c` gives ("a", ("b", "c"), place); `place` is "module" (run when the module is imported, class bodies
    included), "function" (inside a function, method or lambda: a lazy import) or "typing" (`if TYPE_CHECKING:`)."""
    found: list[tuple[str, tuple[str, ...], str]] = []

    def visit(node: ast.AST, place: str) -> None:
        if isinstance(node, ast.Import):
            found.extend((alias.name, (), place) for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            assert not node.level, f"{path}: a relative import (from {'.' * node.level}{node.module or ''} ...)"
            found.append((str(node.module), tuple(alias.name for alias in node.names), place))
        elif isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda):
            place = "function"
        elif isinstance(node, ast.If) and place == "module" and "TYPE_CHECKING" in ast.unparse(node.test):
            for child in node.body:
                visit(child, "typing")
            for child in node.orelse:
                visit(child, place)
            return
        for child in ast.iter_child_nodes(node):
            visit(child, place)

    visit(ast.parse(path.read_text()), "module")
    return found


SPEC = re.compile(r"langtraj\.(\w+)(\.\w+)*:\w+")
"""An object named by a "module:Name" string (`registry.import_object`): an import all the same, made at run time."""


def _spec_packages(path: Path) -> set[str]:
    """The langtraj packages a file names in "langtraj.module:Name" strings (a suite's environment class, a
    registry's entries), which it imports when it resolves them."""
    constants = (n.value for n in ast.walk(ast.parse(path.read_text())) if isinstance(n, ast.Constant))
    return {m[1] for value in constants if isinstance(value, str) and (m := SPEC.fullmatch(value))}


def _imported_packages(path: Path) -> set[str]:
    """The langtraj packages (and top-level modules) a file imports, at any level, "module:Name" strings included."""
    found = _spec_packages(path)
    for module, names, _ in _imports(path):
        if module == "langtraj":  # `from langtraj import x`
            found |= {name for name in names if not name.startswith("__")}
        elif module.startswith("langtraj."):
            found.add(module.split(".")[1])
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


def _imported_modules(path: Path, modules: set[str]) -> set[str]:
    """The langtraj modules a file imports, at any level (`from package import submodule` imports the submodule)."""
    found: set[str] = set()
    for module, names, _ in _imports(path):
        if module == "langtraj" or module.startswith("langtraj."):
            submodules = {f"{module}.{name}" for name in names} & modules
            found |= submodules or {module}
    return found


def _cycles(graph: dict[str, set[str]]) -> list[frozenset[str]]:
    """The strongly connected parts of more than one module of an import graph (Tarjan's algorithm): modules that
    import each other, directly or through others."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[frozenset[str]] = []

    def connect(module: str) -> None:
        index[module] = low[module] = len(index)
        stack.append(module)
        on_stack.add(module)
        for target in sorted(graph[module]):
            if target not in index:
                connect(target)
                low[module] = min(low[module], low[target])
            elif target in on_stack:
                low[module] = min(low[module], index[target])
        if low[module] == index[module]:
            part = set()
            while True:
                member = stack.pop()
                on_stack.discard(member)
                part.add(member)
                if member == module:
                    break
            if len(part) > 1:
                found.append(frozenset(part))

    for module in sorted(graph):
        if module not in index:
            connect(module)
    return found


def test_no_two_modules_import_each_other():
    modules = {}
    for path in SRC.rglob("*.py"):
        name = ".".join(path.relative_to(SRC.parent).with_suffix("").parts).removesuffix(".__init__")
        modules[name] = path
    names = set(modules)
    graph = {m: {t for t in _imported_modules(p, names) if t in names and t != m} for m, p in modules.items()}
    found = [
        "modules importing each other: " + "; ".join(f"{m} imports {sorted(graph[m] & cycle)}" for m in sorted(cycle))
        for cycle in _cycles(graph)
    ]
    assert not found, "\n".join(found)


def test_heavy_third_party_packages_are_imported_where_the_design_says():
    found = []
    for path in sorted(SRC.rglob("*.py")):
        package = _top_package(path)
        for module, _, place in _imports(path):
            top = module.split(".")[0]
            if top in LAZY_ONLY and place != "function":
                found.append(f"{path.relative_to(SRC)} imports {module} outside a function")
            if top == "torch" and place != "typing" and RANK.get(package, len(LAYERS)) < RANK[TORCH_FROM]:
                found.append(f"{path.relative_to(SRC)} imports {module} below the layer of langtraj.{TORCH_FROM}")
    assert not found, "\n".join(found)


def test_the_checks_read_imports_at_every_level(tmp_path):
    source = tmp_path / "module.py"
    source.write_text(
        "from typing import TYPE_CHECKING\n"
        "import langtraj.scenario\n"
        "if TYPE_CHECKING:\n"
        "    import torch\n"
        "class A:\n"
        "    from langtraj.model import features\n"
        "    def plan(self):\n"
        "        from langtraj.cli import simulate\n"
        "        from langtraj import sim\n"
        "        import ray\n"
        "ENV = 'langtraj.env:LangTrajEnv'  # resolved at run time: an import all the same\n"
        "NOTE = 'see langtraj.studio for more'\n"
    )
    assert _imported_packages(source) == {"scenario", "model", "cli", "sim", "env"}
    places = {module: place for module, _, place in _imports(source)}
    assert places == {
        "typing": "module",
        "langtraj.scenario": "module",
        "torch": "typing",
        "langtraj.model": "module",
        "langtraj.cli": "function",
        "langtraj": "function",
        "ray": "function",
    }
    modules = {"langtraj.cli.simulate", "langtraj.model.features", "langtraj.sim", "langtraj.scenario"}
    assert _imported_modules(source, modules) == modules
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [frozenset("abc")]


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
