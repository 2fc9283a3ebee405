"""``axis_republish``: ``image_raw/compressed`` (JPEG) → ``image_raw`` (``sensor_msgs/Image``, bgr8).

The thesis ran image_transport's republish node for this (§6, Table 6.5: the raw topic is ~10× the
compressed one, so it belongs next to its consumer, not on the robot's link). This node decodes with
``cv2.imdecode`` and is lazy: it subscribes to the compressed topic only while someone subscribes to
``image_raw`` (checked on publisher-matched events and a 10 Hz timer), so it costs nothing otherwise.

``input`` = ``h264``: it decodes the stream node's ``image_raw/ffmpeg`` (``FFMPEGPacket``) instead, with
:class:`~axis_ptz_ros2.streaming.receiver.AccessUnitReceiver`: nothing before an IDR, nothing after a lost or corrupt
access unit until the next IDR (never a picture predicted from frames it did not see); errors are counted.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
from ffmpeg_image_transport_msgs.msg import FFMPEGPacket
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.node import Node
from rclpy.subscription import Subscription
from sensor_msgs.msg import CompressedImage, Image

from axis_ptz_ros2.media.pyav import PyAvUnavailableError
from axis_ptz_ros2.nodes.common import STREAM_QOS, VIDEO_QOS, ParamSpec, publisher
from axis_ptz_ros2.nodes.live_params import LiveParams
from axis_ptz_ros2.nodes.runner import run_nodes
from axis_ptz_ros2.streaming.receiver import AccessUnitReceiver

PARAMS: tuple[ParamSpec, ...] = (
    ParamSpec("lazy", True, "subscribe to the input only while image_raw has subscribers"),
    ParamSpec(
        "input",
        "jpeg",
        "what to decode: image_raw/compressed (jpeg) or image_raw/ffmpeg (h264)",
        choices=("jpeg", "h264"),
        read_only=True,
    ),
)


class RepublishNode(Node):
    """Decode JPEG frames to bgr8 images, only on demand."""

    def __init__(self, name: str = "axis_republish", **kwargs: Any) -> None:
        """``kwargs`` go to :class:`rclpy.node.Node` (``context=``, ``parameter_overrides=``, ``namespace=``)."""
        super().__init__(name, **kwargs)
        self._live = LiveParams(self, PARAMS, on_change=lambda _names: self._update())  # lazy: live
        self._h264 = self._live.params["input"] == "h264"
        self._receiver: AccessUnitReceiver | None = None
        self._sub: Subscription | None = None
        self.decoded = 0
        self.failed = 0
        events = PublisherEventCallbacks(matched=lambda _info: self._update())
        self._pub = publisher(self, Image, "image_raw", STREAM_QOS, event_callbacks=events)
        self._timer = self.create_timer(0.1, self._update)
        self._update()

    @property
    def subscribed(self) -> bool:
        """Whether the compressed topic is subscribed right now."""
        return self._sub is not None

    def _update(self) -> None:
        want = not self._live.params["lazy"] or self._pub.get_subscription_count() > 0
        if want and self._sub is None:
            if self._h264:
                try:
                    self._receiver = AccessUnitReceiver()  # a new subscription waits for an IDR
                except PyAvUnavailableError as err:
                    self.get_logger().error(f"{err}; republishing the MJPEG topic image_raw/compressed instead")
                    self._h264 = False
                    self._update()
                    return
                self._sub = self.create_subscription(FFMPEGPacket, "image_raw/ffmpeg", self._on_packet, VIDEO_QOS)
            else:
                self._sub = self.create_subscription(
                    CompressedImage, "image_raw/compressed", self._on_compressed, STREAM_QOS
                )
        elif not want and self._sub is not None:
            self.destroy_subscription(self._sub)
            self._sub = None

    def _on_packet(self, msg: FFMPEGPacket) -> None:
        receiver = self._receiver
        if receiver is None:
            return
        picture = receiver.feed(bytes(msg.data), int(msg.pts))
        self.failed = receiver.decoder_errors + receiver.stats.lost  # waiting for the first IDR is no failure
        if picture is None:
            return
        self._publish(msg.header, picture.image)

    def _on_compressed(self, msg: CompressedImage) -> None:
        buf = np.frombuffer(msg.data, dtype=np.uint8)
        img = cv2.imdecode(buf, cv2.IMREAD_COLOR) if buf.size else None
        if img is None:
            self.failed += 1
            self.get_logger().warning(
                f"cannot decode a {msg.format!r} frame of {buf.size} bytes", throttle_duration_sec=5.0
            )
            return
        self._publish(msg.header, img)

    def _publish(self, header: Any, img: np.ndarray) -> None:
        out = Image()
        out.header = header
        out.height, out.width = int(img.shape[0]), int(img.shape[1])
        out.encoding = "bgr8"
        out.is_bigendian = 0
        out.step = int(img.shape[1] * 3)
        out._data = img.data  # noqa: SLF001 - a C-contiguous buffer; rclpy's serialisation copies it once
        self._pub.publish(out)
        self.decoded += 1


def main(args: list[str] | None = None) -> int:
    """``axis_republish``: the decoder on its own."""
    return run_nodes([RepublishNode], args)


if __name__ == "__main__":
    raise SystemExit(main())
