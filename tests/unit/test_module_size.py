"""No product module is over 500 lines (issue 38): a module that grows past that is split along its jobs.

The product is every ``*.py`` under ``axis_ptz_ros2/axis_ptz_ros2/`` (sub-packages included); a module's lines are
counted as ``wc -l`` counts them: its newline characters.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.unit.test_package_imports import PACKAGE, ROOT

pytestmark = pytest.mark.unit

MAX_LINES = 500


def line_count(path: Path) -> int:
    """The lines of ``path`` as ``wc -l`` counts them (newline characters; a last line without one is not counted)."""
    return path.read_bytes().count(b"\n")


def product_modules() -> list[Path]:
    """Every Python module of the product, sub-packages included."""
    return sorted(PACKAGE.rglob("*.py"))


def test_lines_are_counted_as_wc_counts_them(tmp_path: Path) -> None:
    cases = {"": 0, "x = 1": 0, "x = 1\n": 1, "a\nb\n": 2, "a\n\n\nb": 3, "é\r\nü\r\n": 2}
    for i, (text, expected) in enumerate(cases.items()):
        path = tmp_path / f"m{i}.py"
        path.write_bytes(text.encode("utf-8"))
        assert line_count(path) == expected, repr(text)


def test_every_module_of_the_product_is_seen() -> None:
    modules = {p.relative_to(PACKAGE).as_posix() for p in product_modules()}
    assert len(modules) > 100
    for nested in ("geometry.py", "vapix/client.py", "sim/http/server.py", "nodes/ptz_node.py", "__init__.py"):
        assert nested in modules, nested


def test_no_product_module_is_over_500_lines() -> None:
    over = {p.relative_to(ROOT).as_posix(): n for p in product_modules() if (n := line_count(p)) > MAX_LINES}
    assert not over, f"modules over {MAX_LINES} lines (split each along its jobs): " + ", ".join(
        f"{name} ({n})" for name, n in sorted(over.items(), key=lambda item: -item[1])
    )
