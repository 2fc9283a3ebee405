"""``axis_camera``: the whole camera driver in one process — :class:`StreamNode` (MJPEG → images) and
:class:`PtzNode` (control, state, joint states, transforms) on one executor (:func:`run_nodes`).

Parameters given with ``--ros-args -p name:=value`` apply to both nodes (``hostname``, ``port``, ``auth``,
``camera_model``, … are shared names); ``-r __ns:=/robot/axis`` puts both under one namespace.

Several cameras in one process: ``axis_camera --cameras /front,/rear --ros-args --params-file cams.yaml``
starts one stream + PTZ pair per namespace; each camera's own parameters (``hostname``, ``port``, …) come from
the parameters file under ``/front/axis_stream``, ``/front/axis_ptz``, … (``/**`` for the shared ones). Do not
add ``-r __ns:=`` then: a global namespace remap would put every pair in the same namespace.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from typing import Any

from rclpy.node import Node

from axis_ptz_ros2.nodes.runner import run_nodes


def camera_namespaces(argv: Sequence[str]) -> list[str]:
    """The namespaces of ``--cameras`` (before ``--ros-args``); ``[]`` = one camera in the command line's
    namespace. Raises ``SystemExit`` with a usage message for a malformed list."""
    from rclpy.utilities import remove_ros_args

    ap = argparse.ArgumentParser(prog="axis_camera", description="stream + PTZ nodes of one or more cameras")
    ap.add_argument(
        "--cameras",
        default="",
        help="comma-separated namespaces, one stream + PTZ pair each (e.g. /front,/rear)",
    )
    opts, _unknown = ap.parse_known_args(list(remove_ros_args(list(argv)))[1:])
    names = [n.strip() for n in str(opts.cameras).split(",") if n.strip()]
    out = []
    for n in names:
        ns = n if n.startswith("/") else "/" + n
        if ns in out:
            ap.error(f"--cameras names {ns} twice")
        out.append(ns)
    return out


def main(args: list[str] | None = None) -> int:
    """Run the stream node and the PTZ node of each camera together until Ctrl-C."""
    argv = args if args is not None else sys.argv
    cameras: list[str | None] = [*camera_namespaces(argv)] or [None]  # None: the command line's namespace
    factories: list[Callable[[], Node]] = []
    for ns in cameras:
        factories += camera_pair(ns)
    return run_nodes(factories, argv)


def camera_pair(namespace: str | None, **node_kwargs: Any) -> list[Callable[[], Node]]:
    """The factories of one camera's stream and PTZ nodes (in that order), wired in-process: the stream node's
    ``camera_info`` takes the PTZ node's polled zoom directly instead of deserialising ``ptz/state`` at 20 Hz
    (the composed process then costs about what its two nodes cost alone; bench/bench_cpu.py). ``node_kwargs`` go
    to both nodes (``context=``, ``parameter_overrides=``)."""
    from axis_ptz_ros2.nodes.ptz_node import PtzNode
    from axis_ptz_ros2.nodes.stream_node import StreamNode

    kwargs: dict[str, Any] = dict(node_kwargs) if namespace is None else {**node_kwargs, "namespace": namespace}
    made: list[StreamNode] = []

    def stream() -> Node:
        node = StreamNode(**kwargs)
        made.append(node)
        return node

    def ptz() -> Node:
        node = PtzNode(**kwargs)
        node.add_zoom_listener(made[-1].zoom_sink())
        return node

    return [stream, ptz]


if __name__ == "__main__":
    raise SystemExit(main())
