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
    from axis_ptz_ros2.nodes.ptz_node import PtzNode
    from axis_ptz_ros2.nodes.stream_node import StreamNode

    argv = args if args is not None else sys.argv
    namespaces = camera_namespaces(argv)
    factories: list[Callable[[], Node]] = []
    if not namespaces:
        factories = [StreamNode, PtzNode]
    for ns in namespaces:
        factories.append(lambda ns=ns: StreamNode(namespace=ns))  # type: ignore[misc]
        factories.append(lambda ns=ns: PtzNode(namespace=ns))  # type: ignore[misc]
    return run_nodes(factories, argv)


if __name__ == "__main__":
    raise SystemExit(main())
