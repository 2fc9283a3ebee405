"""The installed package holds no test tooling and only the simulators use the simulator (issue 24, item 3).

Read from the package's real import graph (``ast``: every ``import``/``from … import`` anywhere in a module —
also inside functions and ``TYPE_CHECKING`` blocks — with relative imports resolved, and
``importlib.import_module("…")`` with a literal name):

- nothing under ``axis_ptz_ros2/`` imports ``axis_ptz_ros2.sim`` except ``axis_ptz_ros2/sim/`` itself and the
  simulated robot's nodes (``nodes/panorama_sim.py``, ``nodes/laser_sim.py``): the product (the calibration
  tool among it) runs without the simulator; the simulated-board picker is a plug-in in ``tests/support/``;
- nothing in the package imports ``tests`` (test tooling lives in ``tests/support/``, the demo in ``scripts/``).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "axis_ptz_ros2" / "axis_ptz_ros2"
pytestmark = pytest.mark.unit

#: Modules outside ``axis_ptz_ros2.sim`` that may import it: the simulated robot's sensors.
SIM_USERS = {"axis_ptz_ros2.nodes.panorama_sim", "axis_ptz_ros2.nodes.laser_sim"}


def module_name(path: Path) -> str:
    """``…/axis_ptz_ros2/a/b.py`` → ``axis_ptz_ros2.a.b`` (a package's ``__init__.py`` → the package)."""
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def imported_names(source: str, module: str, is_package: bool = False) -> set[str]:
    """Every module ``source`` (the text of ``module``) may import; ``from x import y`` gives ``x`` and ``x.y``
    (``y`` may be a submodule). Imports under ``if TYPE_CHECKING:`` count like any other: a module whose
    annotations name another cannot be read or type-checked without it."""
    package = module if is_package else module.rpartition(".")[0]
    out: set[str] = set()
    tree = ast.parse(source)
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                name = ".".join([*base, node.module] if node.module else base)
            else:
                name = node.module or ""
            out.add(name)
            out.update(f"{name}.{a.name}" for a in node.names)
        elif (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Attribute | ast.Name)
            and (node.func.attr if isinstance(node.func, ast.Attribute) else node.func.id) == "import_module"
            and node.args
            and isinstance(node.args[0], ast.Constant)
            and isinstance(node.args[0].value, str)
        ):
            out.add(node.args[0].value)
    return out


def import_graph() -> dict[str, set[str]]:
    """Module → the modules it imports, for every module of the package (see :func:`imported_names`)."""
    graph = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        name = module_name(path)
        source = path.read_text(encoding="utf-8")
        graph[name] = imported_names(source, name, path.name == "__init__.py")
    return graph


def _is(name: str, root: str) -> bool:
    return name == root or name.startswith(root + ".")


def test_the_scanner_sees_every_form_of_import() -> None:
    src = """
import tests.support.stamps
from typing import TYPE_CHECKING
if TYPE_CHECKING:
    from ..sim.scene import Scene
def f():
    from .. import sim
    importlib.import_module("axis_ptz_ros2.sim.cli")
    from . import picking
"""
    names = imported_names(src, "axis_ptz_ros2.calibration.capture")
    assert {"tests.support.stamps", "axis_ptz_ros2.sim.scene", "axis_ptz_ros2.sim", "axis_ptz_ros2.sim.cli"} <= names
    assert "axis_ptz_ros2.calibration.picking" in names
    assert "axis_ptz_ros2.sim" in imported_names("from . import server", "axis_ptz_ros2.sim", is_package=True)
    # and on the real package: the simulated robot's nodes do use the simulator
    graph = import_graph()
    assert len(graph) > 50
    for user in SIM_USERS:
        assert any(_is(m, "axis_ptz_ros2.sim") for m in graph[user]), user


def test_only_the_simulators_import_the_simulator() -> None:
    offenders = {
        module: sorted(m for m in imports if _is(m, "axis_ptz_ros2.sim"))
        for module, imports in import_graph().items()
        if not _is(module, "axis_ptz_ros2.sim") and module not in SIM_USERS
    }
    offenders = {k: v for k, v in offenders.items() if v}
    assert offenders == {}, f"the product imports the simulator: {offenders}"


def test_the_package_does_not_import_the_tests() -> None:
    offenders = {module: sorted(m for m in imports if _is(m, "tests")) for module, imports in import_graph().items()}
    offenders = {k: v for k, v in offenders.items() if v}
    assert offenders == {}, f"test tooling imported by the package: {offenders}"
