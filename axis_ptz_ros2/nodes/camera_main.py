"""``axis_camera``: the whole camera driver in one process — :class:`StreamNode` (MJPEG → images) and
:class:`PtzNode` (control, state, joint states, transforms) on one multi-threaded executor.

Parameters given with ``--ros-args -p name:=value`` apply to both nodes (``hostname``, ``port``, ``auth``,
``camera_model``, … are shared names); ``-r __ns:=/robot/axis`` puts both under one namespace.
"""

from __future__ import annotations

import sys

from axis_ptz_ros2.nodes.common import run_nodes


def main(args: list[str] | None = None) -> int:
    """Run the stream node and the PTZ node together until Ctrl-C."""
    from axis_ptz_ros2.nodes.ptz_node import PtzNode
    from axis_ptz_ros2.nodes.stream_node import StreamNode

    return run_nodes([StreamNode, PtzNode], args if args is not None else sys.argv)


if __name__ == "__main__":
    raise SystemExit(main())
