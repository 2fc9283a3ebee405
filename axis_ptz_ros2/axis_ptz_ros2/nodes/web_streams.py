"""The web console's video: image topics subscribed only while an HTTP client watches them, relayed as they are.

Each stream (``ptz``, ``panorama``, ``overlay``) has a :class:`~axis_ptz_ros2.web.relay.FrameSlot` the HTTP
threads read from; the PTZ video also has an :class:`~axis_ptz_ros2.web.h264relay.H264Slot` (FFMPEGPacket access
units for WebCodecs pages). When the first client comes or the last goes, the HTTP thread triggers a guard
condition and the executor subscribes to exactly the topics someone watches; the H.264 topic only while the PTZ
video is H.264 (:meth:`ConsoleStreams.set_codec`: the console's ``codec``, by default the stream's). What arrives
of the PTZ video is metered for the page and reported on ``video/feedback`` (the stream node's link adaptation;
decode errors ask it for an IDR). ROS glue: the slots and the page's meter are ``web/``'s.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

from ffmpeg_image_transport_msgs.msg import FFMPEGPacket
from rclpy.callback_groups import CallbackGroup, MutuallyExclusiveCallbackGroup
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node
from sensor_msgs.msg import CompressedImage

from axis_ptz_ros2.nodes.common import STREAM_QOS, VIDEO_QOS, stamp_s
from axis_ptz_ros2.nodes.link_monitor import FeedbackPublisher
from axis_ptz_ros2.streaming.receiver import PtsGaps
from axis_ptz_ros2.web.h264relay import H264Slot
from axis_ptz_ros2.web.relay import FrameSlot
from axis_ptz_ros2.web.view import ConsoleModel


def _payload(data: Any) -> bytes:  # noqa: ANN401 - a message's uint8[] field (array.array or bytes)
    return data.tobytes() if hasattr(data, "tobytes") else bytes(data)


class ConsoleStreams:
    """The console's image and H.264 subscriptions, slots and link feedback (see the module docstring)."""

    def __init__(
        self,
        node: Node,
        topics: Mapping[str, str],
        h264_topic: str,
        model: ConsoleModel,
        feedback_group: CallbackGroup,
    ) -> None:
        """``topics``: stream name → image topic (``ptz`` first); ``h264_topic``: '' = MJPEG only;
        ``feedback_group``: the group of the ``video/feedback`` timer."""
        self._node = node
        self._topics = dict(topics)
        self._h264_topic = h264_topic
        self._model = model
        self.slots = {n: FrameSlot(n, self._on_watchers) for n in self._topics}
        self._image_subs: dict[str, Any] = {}
        # what the relayed PTZ video looks like on arrival, for the stream's link adaptation (video/feedback)
        self.feedback = FeedbackPublisher(node, self._topics["ptz"], callback_group=feedback_group)
        self.h264 = H264Slot("ptz", self._on_watchers, lambda: self.feedback.add_errors(1))
        self._pts_gaps = PtsGaps()  # access units lost on the way (pts gaps): video/feedback's ``lost``
        self._h264_sub: Any = None
        self.codec = ""  # the PTZ video's codec: mjpeg, h264, '' = none yet (set_codec)
        self._group = MutuallyExclusiveCallbackGroup()
        self._reconcile_gc = node.create_guard_condition(self._reconcile, self._group)

    def _on_watchers(self, name: str, count: int) -> None:
        """HTTP thread: the first client came or the last went; let the executor (un)subscribe."""
        self._reconcile_gc.trigger()

    def set_codec(self, codec: str) -> None:
        """The PTZ video is ``codec`` now (``mjpeg``, ``h264``, ``''`` = none yet): the H.264 subscription follows
        (dropped unless ``h264``); any thread."""
        self.codec = codec
        self._reconcile_gc.trigger()

    def _subscribe(self, msg_type: Any, topic: str, callback: Callable[[Any], None], qos: Any) -> Any:  # noqa: ANN401
        return self._node.create_subscription(
            msg_type,
            topic,
            callback,
            qos,
            callback_group=self._group,
            # no QoS-event waitables: rclpy's executor crashes (InvalidHandle) when a subscription's
            # event handler is destroyed while another thread builds the wait set, as happens here
            # whenever the last viewer leaves
            event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False),
        )

    def _reconcile(self) -> None:
        """Executor: subscribe to exactly the image topics someone watches."""
        for name, slot in self.slots.items():
            want = slot.watchers > 0
            have = name in self._image_subs
            if want and not have:
                self._image_subs[name] = self._subscribe(
                    CompressedImage, self._topics[name], self._frame_callback(name), STREAM_QOS
                )
            elif have and not want:
                self._node.destroy_subscription(self._image_subs.pop(name))
        want = self.h264.watchers > 0 and bool(self._h264_topic) and self.codec == "h264"
        if want and self._h264_sub is None:
            self._pts_gaps = PtsGaps()  # a new subscription joins the stream where it is: no gap to count
            self._h264_sub = self._subscribe(FFMPEGPacket, self._h264_topic, self._on_h264, VIDEO_QOS)
        elif self._h264_sub is not None and not want:
            self._node.destroy_subscription(self._h264_sub)
            self._h264_sub = None
        # the reports name the topic watched (their frame_id): the stream node takes decode errors as H.264's only
        # from a report about an H.264 topic, and MJPEG reports while the stream is H.264 as the MJPEG share's
        watched = self._h264_topic if self._h264_sub is not None else self._topics["ptz"]
        if self._node.resolve_topic_name(watched) != self.feedback.topic:
            self.feedback.retarget(watched)
        if "ptz" in self._image_subs or self._h264_sub is not None:
            self.feedback.watch()
        else:
            self.feedback.stop()

    def _on_h264(self, msg: FFMPEGPacket) -> None:
        data = _payload(msg.data)
        stamp = stamp_s(msg.header.stamp)
        self._pts_gaps.see(int(msg.pts))
        self.feedback.lost = self._pts_gaps.lost
        self.feedback.add(msg, len(data))
        self._model.ptz_frame(len(data), stamp)
        if not self.h264.publish(data, bool(msg.flags & 1), stamp):
            self._node.get_logger().debug(f"H.264 access unit refused: {self.h264.last_refusal}")

    def _frame_callback(self, name: str) -> Callable[[CompressedImage], None]:
        slot = self.slots[name]

        def cb(msg: CompressedImage) -> None:
            data = _payload(msg.data)
            if name == "ptz" and self._h264_sub is None:  # while H.264 is watched, the reports are about it
                self.feedback.add(msg, len(data))
                self._model.ptz_frame(len(data), stamp_s(msg.header.stamp))
            slot.publish(data)

        return cb

    def subscribed(self, name: str) -> bool:
        """True while the image topic of stream ``name`` is subscribed (``ptz.h264``: the H.264 topic)."""
        if name == "ptz.h264":
            return self._h264_sub is not None
        return name in self._image_subs

    def _published(self, topic: str) -> bool:
        node = self._node
        return node.count_publishers(node.resolve_topic_name(topic)) > 0

    def state(self) -> dict[str, Any]:
        """The page's ``stream``, ``h264`` and ``panorama`` sections."""
        return {
            "stream": {"watchers": {n: sl.watchers for n, sl in self.slots.items()}},
            "h264": {
                "available": self.codec == "h264" and bool(self._h264_topic) and self._published(self._h264_topic),
                "subscribed": self._h264_sub is not None,
                "watchers": self.h264.watchers,
                **self.h264.counters(),
            },
            "panorama": {
                "available": self._published(self._topics["panorama"]),
                "overlay": "overlay" in self._topics and self._published(self._topics["overlay"]),
            },
        }

    def close(self) -> None:
        """End every stream (before the HTTP server stops)."""
        for s in self.slots.values():
            s.close()
        self.h264.close()
