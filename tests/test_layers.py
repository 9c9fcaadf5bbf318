"""The package's import graph: layers by role, imports running one way, no circles.

Every import of a vesicle_core module counts, also those inside functions: a circle through a function-level
import is still a circle, it only fails later.
"""

import ast
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parents[1] / "vesicle_core"

#: lower numbers are lower layers; a module may import its own subpackage and strictly lower layers only.
#: Equal numbers are siblings that must not import each other (the solver and the analysis above all).
LAYERS = {
    "": 0,  # the base: errors, io, xp (the array-module switch), the package's __init__ (version)
    "model": 1,
    "data": 2,
    "geometry": 2,
    "solver": 3,
    "analysis": 3,
    "validation": 4,
    "viz": 5,
    "cli": 6,
}


def _module_name(path: Path) -> str:
    parts = path.relative_to(PKG.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in PKG.rglob("*.py")}


def _resolve(node: ast.ImportFrom, here: str, is_package: bool) -> str:
    if node.level == 0:
        return node.module or ""
    base = here.split(".") if is_package else here.split(".")[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def _edges() -> dict[str, set[str]]:
    mods = _modules()
    graph = {m: set() for m in mods}
    for name, path in mods.items():
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            targets = []
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = _resolve(node, name, path.name == "__init__.py")
                # `from pkg import mod` imports the module pkg.mod when there is one
                targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in mods else base for a in node.names]
            for t in targets:
                if t.startswith("vesicle_core") and t != name:
                    while t not in mods:  # `import vesicle_core.solver.stokes.x` style: walk up to a module
                        t = t.rpartition(".")[0]
                    if t != name:
                        graph[name].add(t)
    return graph


def _layer(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 2 or (len(parts) == 2 and parts[1] in LAYERS) else ""


def _against_layers(graph) -> list[str]:
    return sorted(f"{s} -> {d}" for s, ts in graph.items() for d in ts
                  if _layer(s) != _layer(d) and not LAYERS[_layer(d)] < LAYERS[_layer(s)])


def _circles(graph) -> list[list[str]]:
    state, stack, circles = {}, [], []

    def visit(m):
        state[m] = 1
        stack.append(m)
        for n in sorted(graph.get(m, ())):
            if state.get(n) == 1:
                circles.append(stack[stack.index(n):] + [n])
            elif n not in state:
                visit(n)
        stack.pop()
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m)
    return circles


def test_every_module_sits_in_a_known_layer():
    unknown = sorted(m for m in _modules() if _layer(m) not in LAYERS)
    assert not unknown, f"modules outside the layers of this test: {unknown}"
    base = sorted(m for m in _modules() if _layer(m) == "")
    assert base == ["vesicle_core", "vesicle_core.errors", "vesicle_core.io", "vesicle_core.xp"], base


def test_imports_run_from_higher_layers_to_lower_ones():
    wrong = _against_layers(_edges())
    assert not wrong, "imports against the layering:\n" + "\n".join(wrong)


def test_the_module_graph_has_no_circles():
    circles = _circles(_edges())
    assert not circles, "import circles: " + "; ".join(" -> ".join(c) for c in circles)


def test_the_graph_sees_function_level_imports():
    """The checker reads imports inside functions too (the solver's lazy imports of its own modules)."""
    edges = _edges()
    assert "vesicle_core.solver.tension" in edges["vesicle_core.solver.integrators"]  # imported inside a method
    assert "vesicle_core.model.modes" in edges["vesicle_core.solver.seeding"]


@pytest.mark.parametrize("graph, rule", [
    ({"vesicle_core.solver.x": {"vesicle_core.analysis.y"}}, _against_layers),  # siblings
    ({"vesicle_core.analysis.y": {"vesicle_core.solver.x"}}, _against_layers),
    ({"vesicle_core.model.p": {"vesicle_core.solver.k"}}, _against_layers),  # a lower layer reaching up
    ({"vesicle_core.data.c": {"vesicle_core.geometry.m"}}, _against_layers),
    ({"vesicle_core.analysis.h": {"vesicle_core.analysis.t"}, "vesicle_core.analysis.t": {"vesicle_core.analysis.h"}},
     _circles),
])
def test_the_rules_catch_a_wrong_graph(graph, rule):
    assert rule(graph)
