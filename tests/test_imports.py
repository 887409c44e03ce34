"""The package's import graph has no cycles, lazy (function-level) imports and modules named
in strings (``importlib.import_module("skymule.x")``, lazy export tables) included."""

from __future__ import annotations

import ast
from pathlib import Path

import skymule

PACKAGE = Path(skymule.__file__).parent


def _module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(path: Path, modules: set[str]) -> set[str]:
    """skymule modules imported anywhere in ``path`` (top level, functions, TYPE_CHECKING),
    or named by a string constant (``"skymule.x"`` or ``"skymule.x:attribute"``): what
    ``importlib`` imports at run time is an edge too."""
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        names: list[str] = []
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names = [node.module] + [f"{node.module}.{alias.name}" for alias in node.names]
        elif isinstance(node, ast.Constant) and isinstance(node.value, str):
            names = [node.value.split(":")[0]]
        found.update(name for name in names if name in modules)
    # every module's import runs the package's __init__ first anyway (its exports are lazy)
    return found - {"skymule"}


def import_graph() -> dict[str, set[str]]:
    files = {_module_name(path): path for path in PACKAGE.rglob("*.py")}
    modules = set(files)
    return {name: _imports(path, modules) - {name} for name, path in files.items()}


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import cycle as a list of modules (first == last), or None."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                return [*path[path.index(nxt) :], nxt]
            if nxt not in state and (cycle := visit(nxt)):
                return cycle
        path.pop()
        state[node] = 2
        return None

    for start in sorted(graph):
        if start not in state and (cycle := visit(start)):
            return cycle
    return None


def test_find_cycle_finds_a_planted_cycle() -> None:
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set()}) is None


def test_a_module_named_in_a_string_is_an_edge(tmp_path: Path) -> None:
    source = tmp_path / "lazy.py"
    source.write_text(
        'import importlib\nimportlib.import_module("skymule.rules.contract")\n'
        'POLICY = "skymule.policies.builtin:Greedy"\nTEXT = "skymule.sim is fast"\n'
    )
    modules = {"skymule.sim", "skymule.rules.contract", "skymule.policies.builtin"}
    assert _imports(source, modules) == {"skymule.rules.contract", "skymule.policies.builtin"}


def test_the_package_has_no_import_cycles() -> None:
    graph = import_graph()
    assert "skymule.rules.contract" in graph
    assert find_cycle(graph) is None, " -> ".join(find_cycle(graph) or [])


def test_the_core_does_not_import_reports_or_the_cli() -> None:
    """Data flows one way: the simulation core never reaches up to reports or commands."""
    graph = import_graph()
    core = [name for name in graph if name.startswith(("skymule.sim", "skymule.policies"))]
    for name in [*core, "skymule.metrics.summary", "skymule.world"]:
        upward = {m for m in graph[name] if m.startswith(("skymule.report", "skymule.cli"))}
        assert not upward, (name, upward)


def test_lower_layers_import_nothing_above_them() -> None:
    """The rules import nothing of skymule but themselves; radio, flight paths and the world
    take the rules from the rules layer (not from sim/); io never reads through report/; the
    compiled summaries take the AADM score from the rules, not from aadm/."""
    graph = import_graph()
    above = {
        "skymule.rules": ("skymule.",),
        "skymule.io": ("skymule.report", "skymule.cli"),
        "skymule.radio.rates": ("skymule.sim",),
        "skymule.flight.paths": ("skymule.sim",),
        "skymule.world": ("skymule.sim",),
        "skymule.sim.compiled_summaries": ("skymule.aadm",),
    }
    for layer, banned in above.items():
        for name in (n for n in graph if n == layer or n.startswith(layer + ".")):
            upward = {
                m for m in graph[name] if m.startswith(banned) and not m.startswith("skymule.rules")
            }
            assert not upward, (name, upward)
