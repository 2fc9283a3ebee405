"""The spin loop of every node process and of the test harness survives an entity destroyed under it."""

from __future__ import annotations

import pytest

pytest.importorskip("rclpy")

import rclpy  # noqa: E402
from rclpy.context import Context  # noqa: E402
from rclpy.exceptions import InvalidHandle  # noqa: E402
from rclpy.executors import MultiThreadedExecutor  # noqa: E402
from std_msgs.msg import String  # noqa: E402

from axis_ptz_ros2.nodes.common import spin_once  # noqa: E402

pytestmark = pytest.mark.ros


def test_spin_once_survives_a_destroyed_event_handler_and_keeps_delivering():
    # The race a fresh-clone run hit (a subscription destroyed by another thread while the executor built its wait
    # set), made deterministic: one subscription's event handler is destroyed while the node still lists it.
    ctx = Context()
    rclpy.init(context=ctx)
    node = rclpy.create_node("spin_probe", context=ctx)
    got: list[str] = []
    broken = node.create_subscription(String, "broken", lambda m: None, 1)
    node.create_subscription(String, "chatter", lambda m: got.append(m.data), 10)
    pub = node.create_publisher(String, "chatter", 10)
    executor = MultiThreadedExecutor(num_threads=2, context=ctx)
    executor.add_node(node)
    try:
        broken.event_handlers[0].destroy()
        with pytest.raises(InvalidHandle):  # what rclpy's own spin_once does: the caller's loop dies
            executor.spin_once(timeout_sec=0.01)
        spin_once(executor, 0.01)  # ours returns, so the loop goes on (the handler is still listed here)
        node.destroy_subscription(broken)  # what the destroying thread does next
        pub.publish(String(data="after"))
        for _ in range(200):
            spin_once(executor, 0.01)
            if got:
                break
        assert got == ["after"]
    finally:
        executor.shutdown(timeout_sec=1.0)
        node.destroy_node()
        rclpy.try_shutdown(context=ctx)

