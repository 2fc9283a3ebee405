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

The graph is the runtime one: imports under ``if TYPE_CHECKING:`` are annotations (the simulator's request handlers
name the camera type they are handed), not dependencies, and are left out.
"""

from __future__ import annotations

import pytest

from tests.unit.test_package_imports import PACKAGE, import_graph

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
    full = import_graph(runtime_only=True)
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


def _cycles() -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan), package ``__init__`` re-exports aside."""
    graph = {m: {t for t in ts if t in GRAPH and not _is_package(t)} for m, ts in GRAPH.items() if not _is_package(m)}
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
        for w in graph.get(v, ()):
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
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def _is_package(module: str) -> bool:
    return (PACKAGE.parent / module.replace(".", "/") / "__init__.py").exists()


def test_no_cycles() -> None:
    assert not _cycles(), _cycles()
