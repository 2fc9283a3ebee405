"""How a ROS child process of the tests and benches spins until it is told to stop: one place for the executor spin
of ``tests/support/link_probe.py`` and of the benches' ROS viewers (``bench_soak_h264.viewer``,
``link_h264_roles.viewer``). The parent stops the child with SIGINT (rclpy's handler ends the spin) or SIGTERM."""

from __future__ import annotations

from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node


def spin_until_stopped(node: Node) -> None:
    """Spin ``node`` on a single-threaded executor until Ctrl-C or rclpy's own SIGINT/SIGTERM handling ends it,
    then shut the executor, the node and rclpy down."""
    import rclpy  # noqa: PLC0415 - rclpy.try_shutdown, next to its use

    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        executor.shutdown(timeout_sec=1.0)
        node.destroy_node()
        rclpy.try_shutdown()
