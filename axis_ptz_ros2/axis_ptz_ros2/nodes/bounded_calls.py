"""Service calls and remote parameter sets from threads outside the executor, each bounded in time.

The web console's HTTP threads call the PTZ and stream nodes through :class:`BoundedCalls`: the executor
answers the call, the HTTP thread waits on an event for at most ``timeout()`` seconds, and a call that cannot
be made or answered becomes a :class:`ServiceError` with the HTTP status to report (503 not available,
504 no answer in time, 502 failed). Remote parameters go through rclpy's ``AsyncParameterClient``.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

from rcl_interfaces.msg import SetParametersResult
from rclpy.callback_groups import CallbackGroup
from rclpy.client import Client
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.task import Future


class ServiceError(Exception):
    """A service call that did not give an answer: (HTTP status, reason)."""

    def __init__(self, status: int, message: str) -> None:
        """``status``: the HTTP status that reports it."""
        super().__init__(message)
        self.status = status


class BoundedCalls:
    """Service calls and remote parameter sets of ``node`` that never wait longer than ``timeout()`` s."""

    def __init__(self, node: Node, timeout: Callable[[], float], callback_group: CallbackGroup) -> None:
        """``timeout`` is read at every call (a live parameter); clients are created in ``callback_group``."""
        self._node = node
        self._timeout = timeout
        self._group = callback_group
        self._param_clients: dict[str, AsyncParameterClient] = {}

    def _wait(self, fut: Future, what: str, timeout: float, deadline: float, on_timeout: Callable[[], None]) -> Any:
        done = threading.Event()
        fut.add_done_callback(lambda _f: done.set())
        if not done.wait(max(0.0, deadline - time.monotonic())):
            on_timeout()
            fut.cancel()
            raise ServiceError(504, f"service {what} did not answer within {timeout:g} s")
        res = fut.result()
        if res is None:
            raise ServiceError(502, f"service {what} failed: {fut.exception()}")
        return res

    def call(self, client: Client, request: Any) -> Any:  # noqa: ANN401 - any service's response
        """The response of ``client`` to ``request`` (ServiceError when there is none in time)."""
        timeout = self._timeout()
        deadline = time.monotonic() + timeout
        if not client.service_is_ready() and not client.wait_for_service(timeout_sec=min(timeout, 1.0)):
            raise ServiceError(503, f"service {client.srv_name} is not available")
        fut = client.call_async(request)
        return self._wait(fut, client.srv_name, timeout, deadline, lambda: client.remove_pending_request(fut))

    def set_parameter(self, node_name: str, param: Parameter) -> SetParametersResult:
        """Set one parameter of the node ``node_name`` (fully qualified); its result (successful, reason)."""
        client = self._param_clients.get(node_name)
        if client is None:
            client = AsyncParameterClient(self._node, node_name, callback_group=self._group)
            self._param_clients[node_name] = client
        timeout = self._timeout()
        deadline = time.monotonic() + timeout
        what = f"{node_name}/set_parameters"
        if not client.services_are_ready() and not client.wait_for_services(timeout_sec=min(timeout, 1.0)):
            raise ServiceError(503, f"service {what} is not available")
        res = self._wait(client.set_parameters([param]), what, timeout, deadline, lambda: None)
        if not res.results:
            return SetParametersResult(successful=False, reason="no answer")
        result: SetParametersResult = res.results[0]
        return result
