"""The stream node against a simulated camera, as the ROS tests build it (one definition; needs rclpy)."""

from __future__ import annotations

from rclpy.parameter import Parameter

from axis_ptz_ros2.nodes.stream_node import StreamNode
from axis_ptz_ros2.sim.camera import SimulatedCamera
from tests.support.harness import RosHarness
from tests.support.sim import FAST_STREAM_PARAMS


def make_stream_node(ros: RosHarness, camera: SimulatedCamera, **params: object) -> StreamNode:
    """A stream node on ``ros``' context (added to it: spun, destroyed with it) reading ``camera``'s MJPEG with the
    tests' fast reconnect timings (:data:`~tests.support.sim.FAST_STREAM_PARAMS`); ``params`` set or override any
    parameter."""
    values = {"port": camera.port, **FAST_STREAM_PARAMS, **params}
    node = StreamNode(context=ros.context, parameter_overrides=[Parameter(k, value=v) for k, v in values.items()])
    ros.add(node)
    return node
