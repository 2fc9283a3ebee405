"""An in-process ROS graph: a private rclpy context with the node processes' executor (multi-threaded, blocking
spin in a background thread: :class:`~axis_ptz_ros2.nodes.runner.Spinner`). Used by the ROS test tier and by
benchmarks that run nodes in one process (test and bench tooling: not part of the installed package)."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import rclpy
from rclpy.context import Context
from rclpy.node import Node

from axis_ptz_ros2.nodes.runner import Spinner, new_executor, retrieve_task_errors, wait_for_running_callbacks
from tests.support.waiting import DEADLINE_SCALE, wait_until

__all__ = ["DEADLINE_SCALE", "RosHarness"]


class RosHarness:
    """A private rclpy context with the node processes' executor spinning in a background thread."""

    def __init__(self) -> None:
        self.context = Context()
        rclpy.init(context=self.context)
        self.executor = new_executor(self.context)
        self.nodes: list[Node] = []
        self._spinner = Spinner(self.executor, "harness-executor").start()

    def add(self, node: Node) -> Node:
        """Spin ``node`` (created with ``context=harness.context``) and destroy it at teardown."""
        self.nodes.append(node)
        self.executor.add_node(node)
        return node

    def probe(self, name: str = "probe") -> Node:
        """A plain node for subscribing/calling in tests."""
        return self.add(Node(name, context=self.context))

    @staticmethod
    def wait_for(predicate: Callable[[], Any], timeout: float = 10.0, period: float = 0.01) -> Any:
        """Poll until ``predicate()`` is truthy; return its value or raise AssertionError on timeout.

        ``timeout`` is a deadline for a condition, never a speed bound (benchmarks measure speed): it is
        multiplied by ``AXIS_TEST_DEADLINE_SCALE`` (default 4) so that a loaded machine only slows a run down.
        """
        return wait_until(predicate, timeout, period)

    def wait_matched(self, pub: Any, timeout: float = 10.0) -> Any:
        """Wait until ``pub`` has matched a subscription and every subscription on its topic in this harness's
        nodes has matched every publisher its node's graph knows, ``pub`` included (both sides of the DDS match:
        a volatile message published before the reader matched the writer is lost). Returns ``pub``."""
        topic = pub.topic_name

        def matched() -> bool:
            if pub.get_subscription_count() == 0:
                return False
            return all(
                sub.get_publisher_count() >= node.count_publishers(topic)
                for node in list(self.nodes)
                for sub in list(node.subscriptions)
                if sub.topic_name == topic
            )

        self.wait_for(matched, timeout)
        return pub

    def call(self, client: Any, request: Any, timeout: float = 10.0) -> Any:
        """Call a service from the test thread while the executor spins in the background."""
        assert client.wait_for_service(timeout_sec=timeout), f"service {client.srv_name} not available"
        fut = client.call_async(request)
        self.wait_for(fut.done, timeout)
        return fut.result()

    def query(self, client: Any, request: Any, timeout: float = 10.0, attempt: float = 5.0) -> Any:
        """Call a service that only reads (``get_parameters``, ``list_parameters``), sending the request again
        every ``attempt`` s until a response comes or ``timeout`` (scaled as :meth:`wait_for`) ends.

        Why: a client's ``service_is_ready()`` turns true when the server's request reader has matched it, but the
        server's response writer may not have matched the client's response reader yet. rmw_fastrtps then waits
        a short while, drops the response with a "failed to send response (timeout)" warning, and the future never
        completes (a fresh-clone CI run waited 80 s on ``get_parameters`` of a node that had just started). A
        request that changes nothing may simply be asked again; never use this for a command."""
        assert client.wait_for_service(timeout_sec=timeout), f"service {client.srv_name} not available"
        deadline = time.monotonic() + timeout * DEADLINE_SCALE
        while True:
            fut = client.call_async(request)
            until = min(deadline, time.monotonic() + attempt)
            if wait_until(fut.done, max(0.0, until - time.monotonic()), scaled=False, raises=False):
                return fut.result()
            client.remove_pending_request(fut)
            if time.monotonic() >= deadline:
                raise AssertionError(f"no response from {client.srv_name} in {timeout * DEADLINE_SCALE:.1f} s")

    def close(self) -> None:
        # stop spinning before anything is destroyed (no callback on a destroyed handle): the executor's shutdown
        # wakes the blocking spin, which ends
        self._spinner.stop(timeout=2.0)
        wait_for_running_callbacks(self.executor, 3.0)
        for n in reversed(self.nodes):
            try:
                self.executor.remove_node(n)
            finally:
                n.destroy_node()
        retrieve_task_errors(self.executor)
        rclpy.try_shutdown(context=self.context)
        if self._spinner.error is not None:  # a callback failed during the test: the test must not pass
            raise self._spinner.error
