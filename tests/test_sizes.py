"""The package stays readable: no function over 80 lines, no module over 500, and one home for each shared helper.

The limits are the house rules of docs/reference/code.md; a function or module that grows past them is split by
role, not
exempted here.
"""

import ast
import functools
import re
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parents[1] / "vesicle_core"
MAX_FUNCTION_LINES = 80
MAX_MODULE_LINES = 500


def _sources():
    return sorted(PKG.rglob("*.py"))


def _long_functions(tree, limit):
    return [(node.name, node.lineno, node.end_lineno - node.lineno + 1) for node in ast.walk(tree)
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) and node.end_lineno - node.lineno + 1 > limit]


def test_no_function_is_longer_than_80_lines():
    long = [f"{p.relative_to(PKG)}:{line} {name} ({n} lines)" for p in _sources()
            for name, line, n in _long_functions(ast.parse(p.read_text()), MAX_FUNCTION_LINES)]
    assert not long, "functions over 80 lines:\n" + "\n".join(long)


def test_no_module_is_longer_than_500_lines():
    big = [f"{p.relative_to(PKG)} ({n} lines)" for p in _sources()
           if (n := len(p.read_text().splitlines())) > MAX_MODULE_LINES]
    assert not big, "modules over 500 lines:\n" + "\n".join(big)


def test_the_length_check_sees_long_functions():
    body = "\n".join(f"    x{i} = {i}" for i in range(85))
    assert _long_functions(ast.parse(f"def f():\n{body}\n"), MAX_FUNCTION_LINES) == [("f", 1, 86)]
    assert _long_functions(ast.parse("def g():\n    return 1\n"), MAX_FUNCTION_LINES) == []


#: (what, pattern, the one module allowed to hold it)
ONE_HOME = [
    ("the array-module switch", r"get_array_module\(", "xp.py"),
    ("copies from the device", r"hasattr\([^)]*[\"']get[\"']\)", "xp.py"),
    ("a cross product", r"np\.cross\(|def _?cross\w*\(", "geometry/surface.py"),
    ("a dot product of vectors", r"def _?dot\(|einsum\(\"ij,ij->i\"", "geometry/surface.py"),
    ("face areas, normals, volume or centroid", r"def (?:face_area_vectors|surface_area|enclosed_volume|"
     r"triangle_areas|volume_centroid|vertex_normals|face_normals)\(", "geometry/surface.py"),
]


def _holders(pattern):
    return sorted(str(p.relative_to(PKG)) for p in _sources() if re.search(pattern, _code(p)))


@functools.cache  # parsed once per test process, not once per ONE_HOME entry (each parses the whole package)
def _code(path):
    """The module without comments and docstrings, so that prose about np.cross does not count."""
    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant) and isinstance(node.value.value, str):
            node.value.value = ""
    return ast.unparse(tree)


@pytest.mark.parametrize(("what", "pattern", "home"), ONE_HOME, ids=[w for w, _, _ in ONE_HOME])
def test_one_home(what, pattern, home):
    assert _holders(pattern) == [home], f"{what} must be defined in {home} only"
