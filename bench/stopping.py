"""How a bench's child process runs until it is told to stop: the one place for the SIGTERM/SIGINT wait of the
simulator children (``pipelines.sim_child``, ``capture_match.sim_child``) and the executor spin of the ROS viewers
(``bench_soak_h264.viewer``, ``link_h264_roles.viewer``). The parent stops a child with SIGINT (``pipelines.Proc``)
or SIGTERM."""

from __future__ import annotations

import signal
import threading
from typing import Any


def wait_for_stop() -> None:
    """Block until this process gets SIGTERM or SIGINT (replaces their handlers)."""
    done = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: done.set())
    signal.signal(signal.SIGINT, lambda *_: done.set())
    done.wait()


def spin_until_stopped(node: Any) -> None:
    """Spin ``node`` on a single-threaded executor until Ctrl-C or rclpy's own SIGINT/SIGTERM handling ends it,
    then shut the executor, the node and rclpy down."""
    import rclpy
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor

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
