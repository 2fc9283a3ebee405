"""The package's import graph (modules as nodes, imports as edges) has no upward arrows and no cycles (issue 24).

Layers, lowest first — a module may import its own layer and the layers below it, never above:

0. the package root (its version), ``tls``, ``strict_yaml``, ``vapix/`` (the camera protocol), ``media/`` (H.264
   bytes: the RTSP reader hands SPS/PPS to it)                         — protocols and formats only
1. ``geometry``, ``pointing``, ``pointcloud``, ``config``, ``camera_info``,
   ``camera_info_store``, ``camera_models``, ``ptz/``, ``streaming/``, ``virtual/``, ``calibration/``,
   ``teleop/``, ``web/``                                              — ROS-free logic
2. ``sim/``                                                          — the simulated camera (ROS-free)
3. ``nodes/``                                                        — ROS glue

and ROS (``rclpy`` and message packages) only in layer 3. The simulator is a stand-in for hardware: the product's
layers below it must not import it (``test_package_imports.py`` checks who may).

Every import counts, also those under ``if TYPE_CHECKING:`` (annotation-only): a module whose annotations name
another cannot be read or type-checked without it, so an annotation is a dependency as much as a call (issue 38).
A handler that must not know its owner is typed against a small interface in a module of its own (e.g.
``sim/view.py``'s ``CameraView``, ``web/handler.py``'s ``ConsoleHost``).
"""

from __future__ import annotations

import pytest

from tests.unit.test_package_imports import PACKAGE, import_graph, imported_names

pytestmark = pytest.mark.unit

ROS_ROOTS = {
    "rclpy", "sensor_msgs", "std_msgs", "geometry_msgs", "axis_ptz_interfaces", "diagnostic_msgs", "nav_msgs",
    "std_srvs", "rcl_interfaces", "action_msgs", "tf2_ros", "tf2_msgs", "ffmpeg_image_transport_msgs",
    "foxglove_msgs", "builtin_interfaces", "ament_index_python",
}  # fmt: skip
LAYER_0 = {"", "tls", "strict_yaml", "vapix", "media"}
LAYER_2 = {"sim"}
LAYER_3 = {"nodes"}
# share-directory look-ups through ament_index when it is installed (optional; both work without it)
ROS_OK_OUTSIDE_NODES = {
    "axis_ptz_ros2.camera_info_store": {"ament_index_python"},
    "axis_ptz_ros2.config": {"ament_index_python"},
}


def _layer(module: str) -> int:
    top = module.split(".")[1] if "." in module else ""
    if top in LAYER_0:
        return 0
    if top in LAYER_2:
        return 2
    if top in LAYER_3:
        return 3
    return 1


def _graph() -> dict[str, set[str]]:
    full = import_graph()
    return {m: {t for t in ts if t in full or t.split(".")[0] in ROS_ROOTS} for m, ts in full.items()}


GRAPH = _graph()


def test_the_graph_is_not_empty() -> None:
    assert len(GRAPH) > 50
    assert "axis_ptz_ros2.vapix.client" in GRAPH["axis_ptz_ros2.nodes.stream_node"] or any(
        m.startswith("axis_ptz_ros2.vapix") for m in GRAPH["axis_ptz_ros2.nodes.stream_node"]
    )


def test_no_upward_imports() -> None:
    bad = []
    for module, targets in GRAPH.items():
        for target in targets:
            if target.startswith("axis_ptz_ros2") and _layer(target) > _layer(module):
                bad.append(f"{module} (layer {_layer(module)}) imports {target} (layer {_layer(target)})")
    assert not bad, "\n".join(sorted(bad))


def test_ros_only_in_nodes() -> None:
    bad = []
    for module, targets in GRAPH.items():
        if _layer(module) == 3:
            continue
        allowed = ROS_OK_OUTSIDE_NODES.get(module, set())
        bad += [
            f"{module} imports {t}" for t in targets if t.split(".")[0] in ROS_ROOTS and t.split(".")[0] not in allowed
        ]
    assert not bad, "\n".join(sorted(bad))


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one node of ``graph`` (Tarjan), each sorted; a node that
    imports itself is one too. Edges to nodes outside ``graph`` are ignored."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []
    counter = [0]

    def visit(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in graph:
                continue
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1 or v in graph.get(v, ()):
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def _is_package(module: str) -> bool:
    return (PACKAGE.parent / module.replace(".", "/") / "__init__.py").exists()


def module_graph(graph: dict[str, set[str]]) -> dict[str, set[str]]:
    """Module → module edges of the package: package ``__init__`` modules left out (importing ``a.b`` runs
    ``a/__init__`` first, so a package that re-exports its submodules would close a loop with each of them)."""
    return {
        m: {t for t in ts if t.startswith("axis_ptz_ros2") and t in graph and not _is_package(t)}
        for m, ts in graph.items()
        if not _is_package(m)
    }


def test_the_cycle_finder_finds_circles() -> None:
    """On small graphs: a two-module circle, a three-module one, a self-import; none in a tree."""
    assert cycles({"a": {"b"}, "b": {"a"}, "c": {"a"}}) == [["a", "b"]]
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a", "d"}, "d": set()}) == [["a", "b", "c"]]
    assert cycles({"a": {"a"}}) == [["a"]]
    assert cycles({"a": {"b", "c"}, "b": {"c"}, "c": {"x"}}) == []


def test_an_annotation_only_circle_is_a_circle() -> None:
    """Two modules that import each other only for annotations (``if TYPE_CHECKING:``) form a circle."""
    owner = "from axis_ptz_ros2.demo.handler import Handler\nclass Owner: ...\n"
    handler = (
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from axis_ptz_ros2.demo.owner import Owner\n"
        "class Handler:\n    owner: Owner\n"
    )
    graph = {
        "axis_ptz_ros2.demo.owner": imported_names(owner, "axis_ptz_ros2.demo.owner"),
        "axis_ptz_ros2.demo.handler": imported_names(handler, "axis_ptz_ros2.demo.handler"),
    }
    assert cycles(graph) == [["axis_ptz_ros2.demo.handler", "axis_ptz_ros2.demo.owner"]]


def test_no_cycles() -> None:
    """No circle anywhere in the package, annotation-only imports included."""
    found = cycles(module_graph(GRAPH))
    assert not found, "import circles (strongly connected modules):\n" + "\n".join(" <-> ".join(c) for c in found)
