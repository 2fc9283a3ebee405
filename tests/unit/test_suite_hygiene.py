"""Every assertion in the test suite can fail: no ``assert True``, no ``... or True``, no empty test body."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

TESTS = Path(__file__).resolve().parents[1]
pytestmark = pytest.mark.unit


def _always_true(node: ast.expr) -> bool:
    """An expression that is truthy whatever the code under test does."""
    if isinstance(node, ast.Constant):
        return bool(node.value)
    if isinstance(node, ast.BoolOp) and isinstance(node.op, ast.Or):
        return any(_always_true(v) for v in node.values)
    if isinstance(node, ast.BoolOp) and isinstance(node.op, ast.And):
        return all(_always_true(v) for v in node.values)
    return False


def _problems(source: str, name: str) -> list[str]:
    out = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Assert) and _always_true(node.test):
            out.append(f"{name}:{node.lineno}: assertion cannot fail: {ast.unparse(node.test)}")
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) and node.name.startswith("test"):
            body = [
                s for s in node.body if not (isinstance(s, ast.Expr) and isinstance(s.value, ast.Constant))
            ]  # docstrings
            if all(isinstance(s, ast.Pass) for s in body):
                out.append(f"{name}:{node.lineno}: {node.name} tests nothing")
    return out


def test_the_checker_finds_what_it_looks_for() -> None:
    bad = (
        "def test_a():\n    assert f() is None or True\n"
        "def test_b():\n    assert 1\n"
        "def test_c():\n    '''doc'''\n    pass\n"
        "def test_d():\n    assert f() or (g() and 'x')\n"
    )
    found = _problems(bad, "x.py")
    assert sorted(p.split(":")[1] for p in found) == ["2", "4", "5"]
    good = "def test_a():\n    assert f() is None or g() > 0\n    assert x or y\n"
    assert _problems(good, "y.py") == []


def test_no_assertion_in_the_suite_is_unfailable() -> None:
    files = sorted(TESTS.rglob("test_*.py"))
    assert len(files) > 20
    problems = [p for f in files for p in _problems(f.read_text(encoding="utf-8"), str(f.relative_to(TESTS)))]
    assert problems == []
