"""The web console's full-quality still: the page's "Still" button (and the teleop key P) as the stream node's
``still/capture``, and the still itself relayed to the page from ``still/compressed``.

The console subscribes to ``still/compressed`` for good (reliable + transient local, depth 1: the last still is
there as soon as the console starts; a still crosses the link only when someone asked for one). Its JPEG goes into
a :class:`~axis_ptz_ros2.web.relay.FrameSlot` as it came (no re-encoding), served at ``GET /video/still.jpg``;
its sequence number, size and stamp are in the page's state (``still``), so every page shows a new still. A
``POST /api/still`` calls the service (bounded in time: ``service_timeout``, at least :data:`STILL_WAIT_S`) and
answers once the still it asked for has arrived here, with the node's message (size and resolution) and ``seq``.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

from rclpy.callback_groups import CallbackGroup, ReentrantCallbackGroup
from rclpy.node import Node
from sensor_msgs.msg import CompressedImage
from std_srvs.srv import Trigger

from axis_ptz_ros2.nodes.bounded_calls import BoundedCalls
from axis_ptz_ros2.nodes.common import LATCHED_QOS, stamp_s
from axis_ptz_ros2.streaming.jpeg import jpeg_size
from axis_ptz_ros2.web.backend import CommandResult
from axis_ptz_ros2.web.relay import FrameSlot

#: the stream node's still topic and service (relative: the console's namespace)
STILL_TOPIC = "still/compressed"
STILL_SERVICE = "still/capture"
#: s: the shortest wait for a still (a full-resolution JPEG over a weak link takes a while)
STILL_WAIT_S = 30.0


class ConsoleStill:
    """The console's still: service client, the subscription, the slot the HTTP threads read."""

    def __init__(self, node: Node, timeout: Callable[[], float], group: CallbackGroup) -> None:
        """``timeout()``: the console's ``service_timeout`` (read at each call); ``group``: the subscription's."""
        self.slot = FrameSlot("still")
        self._lock = threading.Lock()
        self._info: dict[str, Any] = {"seq": 0}
        g = ReentrantCallbackGroup()
        self._wait = lambda: max(STILL_WAIT_S, float(timeout()))
        self._client = node.create_client(Trigger, STILL_SERVICE, callback_group=g)
        self._calls = BoundedCalls(node, self._wait, g)
        node.create_subscription(CompressedImage, STILL_TOPIC, self._on_still, LATCHED_QOS, callback_group=group)

    def _on_still(self, msg: CompressedImage) -> None:
        data = msg.data.tobytes() if hasattr(msg.data, "tobytes") else bytes(msg.data)
        size = jpeg_size(data)
        with self._lock:
            self.slot.publish(data)
            self._info = {
                "seq": self.slot.latest()[0],
                "bytes": len(data),
                "width": size[0] if size else None,
                "height": size[1] if size else None,
                "stamp": stamp_s(msg.header.stamp),
            }

    def ready(self) -> bool:
        """Whether ``still/capture`` answers."""
        return bool(self._client.service_is_ready())

    def state(self) -> dict[str, Any]:
        """The page's ``still`` section: ``seq`` (0 = none yet), ``bytes``, ``width``, ``height``, ``stamp`` (s)."""
        with self._lock:
            return dict(self._info)

    def take(self, _body: dict[str, Any] | None = None) -> CommandResult:
        """``POST /api/still``: call ``still/capture``, answer once the still is here (ServiceError: no answer)."""
        seq = self.slot.latest()[0]
        res = self._calls.call(self._client, Trigger.Request())
        if not res.success:
            return CommandResult(False, f"still: {res.message or 'refused'}", 409)
        got = self.slot.wait_newer(seq, self._wait())
        if got is None:
            return CommandResult(False, f"{res.message}, but it did not arrive here", 504)
        return CommandResult(True, str(res.message), extra={"seq": got[0]})
