"""The import structure: no cycles, the layers import downwards only, and the library never
imports the agents. Read from the source (imports inside functions included), nothing run."""

import ast
import functools
import itertools
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("scara_gym", "agents")
AGENT_LAYERS = ("agents.files", "agents.policies", "agents.algorithms", "agents.experiments", "agents.cli")
"""the agents' layers, lowest first: each may import the ones before it, never after"""
OPTIONAL = {"torch", "stable_baselines3", "casadi", "ray", "rliable", "matplotlib", "yaml", "numba.cuda", "minari"}
"""third-party packages of the install extras: a module importing one at its top may be imported
inside a function, so that the core install runs without them"""


def _module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for package in PACKAGES for p in (ROOT / package).rglob("*.py")}


MODULES = _modules()


def _resolve(name: str) -> str | None:
    """The project module an imported name lives in (a module, or a name in a package's __init__)."""
    while name and name not in MODULES:
        name = name.rpartition(".")[0]
    return name or None


@functools.cache
def _imports(module: str) -> list[tuple[str, bool, int]]:
    """(imported name, inside a function, line) for every import of the module."""
    tree = ast.parse(MODULES[module].read_text())
    package = module if MODULES[module].name == "__init__.py" else module.rpartition(".")[0]
    found = []

    def visit(node, inside: bool) -> None:
        for child in ast.iter_child_nodes(node):
            nested = inside or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda))
            if isinstance(child, ast.Import):
                found.extend((alias.name, inside, child.lineno) for alias in child.names)
            elif isinstance(child, ast.ImportFrom):
                base = child.module or ""
                if child.level:
                    base = ".".join(package.split(".")[:len(package.split(".")) - child.level + 1] + ([base] if base else []))
                found.extend((f"{base}.{alias.name}", inside, child.lineno) for alias in child.names)
            elif isinstance(child, ast.If) and "TYPE_CHECKING" in ast.unparse(child.test):
                continue  # annotations only
            visit(child, nested)

    visit(tree, False)
    return found


@functools.cache
def _edges(include_functions: bool = True) -> dict[str, set[str]]:
    edges = {m: set() for m in MODULES}
    for module in MODULES:
        for name, inside, _ in _imports(module):
            target = _resolve(name)
            if target and target != module and (include_functions or not inside):
                edges[module].add(target)
    return edges


def _top_level_optional(module: str) -> set[str]:
    return {root for name, inside, _ in _imports(module) if not inside
            for root in OPTIONAL if name == root or name.startswith(root + ".")}


def _needs_optional(module: str, seen=None) -> bool:
    """Whether importing the module imports an optional package (itself or through its top-level imports)."""
    seen = set() if seen is None else seen
    if module in seen:
        return False
    seen.add(module)
    return bool(_top_level_optional(module)) or any(_needs_optional(m, seen) for m in _edges(False)[module])


def _layer(module: str) -> int | None:
    for rank, layer in enumerate(AGENT_LAYERS):
        if module == layer or module.startswith(layer + "."):
            return rank
    return None


def test_the_reader_sees_the_modules_and_their_imports():
    """The test has teeth: it finds the modules and edges everyone knows are there."""
    assert {"scara_gym.envs.factory", "agents.cli", "agents.experiments.registry"} <= set(MODULES)
    edges = _edges()
    assert "agents.experiments.registry" in edges["agents.experiments.runs"]
    assert "agents.algorithms.torch_ppo" in edges["agents.experiments.bench"]
    assert _needs_optional("agents.algorithms.torch_ppo") and not _needs_optional("agents.policies.pd")


def test_no_import_cycle():
    edges = _edges()
    state: dict[str, int] = {}
    path: list[str] = []

    def walk(module: str) -> None:
        state[module] = 1
        path.append(module)
        for target in sorted(edges[module]):
            if state.get(target) == 1:
                cycle = path[path.index(target):] + [target]
                pytest.fail("import cycle: " + " -> ".join(cycle))
            if target not in state:
                walk(target)
        path.pop()
        state[module] = 2

    for module in sorted(MODULES):
        if module not in state:
            walk(module)


def test_the_library_never_imports_the_agents():
    offenders = [(m, name, line) for m in MODULES if m.startswith("scara_gym")
                 for name, _, line in _imports(m) if name == "agents" or name.startswith("agents.")]
    assert not offenders, offenders


def test_the_agents_layers_import_downwards_only():
    offenders = []
    for module, targets in _edges().items():
        rank = _layer(module)
        for target in targets:
            other = _layer(target)
            if rank is not None and other is not None and other > rank:
                offenders.append(f"{module} ({AGENT_LAYERS[rank]}) imports {target} ({AGENT_LAYERS[other]})")
    assert not offenders, "\n".join(offenders)


def test_imports_inside_functions_are_for_optional_packages_only():
    """In the agents, a project module imported inside a function must be one that needs an
    optional package (the library keeps lazy imports of its own for the command's start-up)."""
    offenders = []
    for module in (m for m in MODULES if m.startswith("agents")):
        for name, inside, line in _imports(module):
            target = _resolve(name)
            if inside and target is not None and not _needs_optional(target):
                offenders.append(f"{MODULES[module].relative_to(ROOT)}:{line} imports {name} inside a function")
    assert not offenders, "\n".join(offenders)


def test_the_layers_cover_every_agents_module():
    assert all(_layer(m) is not None for m in MODULES if m.startswith("agents.") and m != "agents.__main__"), \
        [m for m in MODULES if m.startswith("agents.") and _layer(m) is None]
    assert list(itertools.accumulate(AGENT_LAYERS, lambda a, b: b)) == list(AGENT_LAYERS)
