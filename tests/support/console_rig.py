"""The robot side a browser test drives: stream node, PTZ node and web console on one simulated camera,
in-process over real DDS (tests/support/harness.py)."""

from __future__ import annotations

from rclpy.parameter import Parameter

from axis_ptz_ros2.nodes.ptz_node import PtzNode
from axis_ptz_ros2.nodes.stream_node import StreamNode
from axis_ptz_ros2.nodes.web_console import WebConsole
from tests.support.harness import RosHarness


def start_console_rig(
    ros: RosHarness, namespace: str, connection: list[Parameter], video: list[Parameter]
) -> WebConsole:
    """Add the three nodes under ``namespace`` (``connection``: how to reach the camera, for both drivers;
    ``video``: the stream node's video parameters); return the console once the PTZ state flows."""
    ros.add(StreamNode(context=ros.context, namespace=namespace, parameter_overrides=connection + video))
    ptz = ros.add(PtzNode(context=ros.context, namespace=namespace, parameter_overrides=connection))
    console = ros.add(
        WebConsole(
            context=ros.context,
            namespace=namespace,
            parameter_overrides=[Parameter("port", value=0), Parameter("service_timeout", value=10.0)],
        )
    )
    ros.wait_for(lambda: ptz.poller.latest is not None, 20.0)
    return console
