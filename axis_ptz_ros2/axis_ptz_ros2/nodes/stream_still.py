"""The stream node's full-quality still on demand: ``still/capture`` (std_srvs/Trigger) → ``still/compressed``.

ROS glue over :class:`~axis_ptz_ros2.streaming.still.StillTaker` (the camera's best JPEG: compression 0 at its full
resolution, fetched on a worker thread with a camera client of its own for each still, so neither the node's
executor nor the stream's discovery client waits for it). The service callback is a coroutine: it starts the
fetch and awaits its outcome, which the worker hands over through a future and a guard condition that wakes the
executor. It is in a reentrant callback group of its own: in the node's default (mutually exclusive) group the
awaiting answer would hold every other callback of the node. So the executor goes on (the node keeps its
single-threaded executor: :func:`~axis_ptz_ros2.nodes.runner.callbacks_serialised` does not count a coroutine
callback; a multi-threaded one works the same), and the answer comes once the still has been published:

* ``still/compressed`` (sensor_msgs/CompressedImage, reliable + transient local, depth 1: a late subscriber gets the
  last still): the camera's bytes as they came, ``frame_id`` as the live images, stamped when the JPEG had arrived;
* the Trigger answer: success and "still 704x576 px, compression 0, 61234 bytes, fetched in 40 ms", or the reason
  (camera unreachable within its connect timeout, an error from the camera) and "a still is already being taken"
  for a request while one is in flight (refused at once, never queued). No message carries credentials.

Link budget: a still goes out on the same link as the live video. For one meter window its rate is reserved out of
the stream's MJPEG bandwidth budget, at most half of it
(:meth:`~axis_ptz_ros2.streaming.controller.VideoController.on_still`): the live stream's next budget judgement
(within 0.25 s) judges it against what is left and jumps once to the level predicted under it; it climbs back once
the still has left the window (h264 mode: the encoder's target is capped until every reader has acknowledged the
still, :class:`~axis_ptz_ros2.streaming.still.StillWindow`). The node does not pace the still: it is one DDS sample,
which rclpy hands to the middleware whole. The weak-link profile (``config/fastdds_weak_link.xml``) paces its writer
with a Fast DDS flow controller; that needs ``RMW_FASTRTPS_PUBLICATION_MODE=AUTO``, and where the middleware refuses
the writer the node runs on without stills, logging why and answering every request with the reason
(:data:`UNAVAILABLE`).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.task import Future
from sensor_msgs.msg import CompressedImage
from std_srvs.srv import Trigger

from axis_ptz_ros2.nodes.common import LATCHED_QOS, MiddlewareRefused, jpeg_format, publisher, stamp_from_ns
from axis_ptz_ros2.streaming.controller import VideoController
from axis_ptz_ros2.streaming.still import STILL_CROSSING_MAX_S, StillOutcome, StillTaker, still_summary
from axis_ptz_ros2.vapix import VapixClient
from axis_ptz_ros2.vapix.models import Resolution

#: s: how often the still's writer is asked whether every reader has acknowledged the still (closing the node ends
#: the waiting within it). Asked without waiting, with the wait in Python: rclpy's ``Publisher.wait_for_all_acked``
#: holds the GIL while it waits, so 0.2 s waits starved the node's frame path for as long as a still crossed (a
#: counting thread ran at 2.7 % of its speed; on 2 Mbit/s + 2 % the live video fell to 1-2 fps)
ACK_POLL_S = 0.05
#: a wait that returns at once (see :data:`ACK_POLL_S`)
NO_WAIT = Duration(seconds=0)

#: the answer (and the error logged at start) when the middleware refused the still's writer
UNAVAILABLE = (
    "still unavailable: the middleware refused the writer of still/compressed. A Fast DDS profile that paces it "
    "(config/fastdds_weak_link.xml) needs RMW_FASTRTPS_PUBLICATION_MODE=AUTO: rmw_fastrtps makes every writer "
    "synchronous otherwise, and Fast DDS refuses a flow controller on a synchronous writer"
)

#: the still's topic and service (relative: they follow the node's namespace)
STILL_TOPIC = "still/compressed"
STILL_SERVICE = "still/capture"


class StillOutput:
    """``still/capture`` and ``still/compressed`` of one stream node (see the module docstring)."""

    def __init__(
        self,
        node: Node,
        client: VapixClient,
        video: VideoController,
        frame_id: str,
        log: Callable[[str], None] | None = None,
        *,
        count: Callable[[float, int], None],
        crossed: Callable[[float], None],
    ) -> None:
        """``client``: the stream's camera client (its configuration and auth counters are shared, not its
        connection or lock); ``video``: the controller that knows the camera's resolutions; ``count(now, nbytes)``:
        what counts a still going out against the budget (the pipeline's ``on_still``, which also tells the encoder
        at once); ``crossed(now)``: told when every reader has acknowledged the still (or the wait for it ended),
        after the answer."""
        self._node = node
        self._video = video
        self._count = count
        self._crossed = crossed
        self._frame_id = frame_id
        self._log = log
        config = client.config
        counters = client.auth_counters
        self.taker = StillTaker(
            lambda: VapixClient(config, auth_counters=counters),
            self._known_resolutions,
            camera_index=config.camera,
            secrets=(config.password,),
        )
        self._closed = threading.Event()
        # None: the middleware refused the still's writer (the reason in ``unavailable``); the node runs on without
        # stills and every request is answered with that reason
        self.pub: Publisher | None = None
        self.unavailable = ""
        try:
            self.pub = publisher(node, CompressedImage, STILL_TOPIC, LATCHED_QOS)
        except MiddlewareRefused as err:
            self.unavailable = f"{UNAVAILABLE} ({str(err).splitlines()[0]})"
            node.get_logger().error(self.unavailable)
        self._wake = node.create_guard_condition(lambda: None)  # the executor resumes the waiting answer
        # a group of its own, reentrant: a second request is answered (refused) while the first awaits its still,
        # and the node's other callbacks never wait for it (the default group is mutually exclusive)
        self.service = node.create_service(
            Trigger, STILL_SERVICE, self._on_capture, callback_group=ReentrantCallbackGroup()
        )

    def _known_resolutions(self) -> tuple[Resolution, ...]:
        video = self._video
        return video.state().resolutions if video.resolutions_known else ()

    async def _on_capture(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        """Start the still on the worker and await its publication (the executor goes on meanwhile)."""
        pub = self.pub
        if pub is None:
            response.success, response.message = False, self.unavailable
            return response
        done: Future = Future()

        def finished(outcome: StillOutcome) -> None:  # worker thread
            try:
                message = self._publish(pub, outcome)
            except Exception as err:  # noqa: BLE001 - the answer must come whatever happened
                message = f"still failed: could not publish it ({type(err).__name__})"
                outcome = StillOutcome(None, message)
            done.set_result((outcome.still is not None, message))
            if not self._closed.is_set():
                self._wake.trigger()
            if outcome.still is not None:
                self._wait_crossed(pub)

        refusal = self.taker.start(finished)
        if refusal is not None:
            response.success, response.message = False, refusal
            return response
        await done
        ok, message = done.result()
        response.success, response.message = bool(ok), str(message)
        if not ok and self._log is not None:
            self._log(message)
        return response

    def _publish(self, pub: Publisher, outcome: StillOutcome) -> str:
        """Worker thread: publish the still on ``pub`` (counted against the budget first); the answer's message."""
        still = outcome.still
        if still is None:
            return outcome.error
        if self._closed.is_set():
            return "still failed: the node is shutting down"
        msg = CompressedImage()
        msg.header.stamp = stamp_from_ns(still.arrival_ns)
        msg.header.frame_id = self._frame_id
        msg.format = jpeg_format(still.components)
        msg._data = still.jpeg  # noqa: SLF001 - the immutable bytes as they are (as the live images)
        self._count(time.monotonic(), len(still.jpeg))
        pub.publish(msg)
        return still_summary(still)

    def _wait_crossed(self, pub: Publisher) -> None:
        """Worker thread, after the answer: wait until every reader has acknowledged the still (asked every
        :data:`ACK_POLL_S` without waiting in rclpy, so the GIL stays free and closing the node ends it), at most
        :data:`~axis_ptz_ros2.streaming.still.STILL_CROSSING_MAX_S`; then tell ``crossed``. A second request
        meanwhile is refused (the taker is busy until this returns)."""
        deadline = time.monotonic() + STILL_CROSSING_MAX_S
        while time.monotonic() < deadline:
            if pub.wait_for_all_acked(NO_WAIT) or self._closed.wait(ACK_POLL_S):
                break
        self._crossed(time.monotonic())

    def close(self, timeout: float = 1.0) -> None:
        """Before the node goes: no publication from here on, the fetch in flight cut (its client closed), joined."""
        self._closed.set()
        self.taker.close(timeout)
