"""``axis_republish``: ``image_raw/compressed`` (JPEG) → ``image_raw`` (``sensor_msgs/Image``, bgr8).

The thesis ran image_transport's republish node for this (§6, Table 6.5: the raw topic is ~10× the
compressed one, so it belongs next to its consumer, not on the robot's link). This node decodes with
``cv2.imdecode`` and is lazy: it subscribes to the compressed topic only while someone subscribes to
``image_raw`` (checked on publisher-matched events and a 10 Hz timer), so it costs nothing otherwise.

What it decodes follows the stream by default (``input`` = ``auto``): the codec the stream node announces on
``video/params`` (latched), switched when it changes, the old subscription dropped (:mod:`axis_ptz_ros2.codec_follow`);
until ``video/params`` is heard it subscribes to no video (logged once). ``input`` = ``jpeg`` or ``h264`` fixes it.

H.264: it decodes the stream node's ``image_raw/ffmpeg`` (``FFMPEGPacket``) with
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

from axis_ptz_ros2.codec_follow import AUTO
from axis_ptz_ros2.media.pyav import PyAvUnavailableError
from axis_ptz_ros2.nodes.codec_follow import follow_stream_codec, no_events
from axis_ptz_ros2.nodes.common import STREAM_QOS, VIDEO_QOS, ParamSpec, publisher
from axis_ptz_ros2.nodes.live_params import LiveParams
from axis_ptz_ros2.nodes.runner import run_nodes
from axis_ptz_ros2.streaming.receiver import AccessUnitReceiver

#: the ``input`` parameter's choices (``jpeg`` is the stream's codec ``mjpeg``)
INPUTS = (AUTO, "jpeg", "h264")

PARAMS: tuple[ParamSpec, ...] = (
    ParamSpec("lazy", True, "subscribe to the input only while image_raw has subscribers"),
    ParamSpec(
        "input",
        AUTO,
        "what to decode: auto = the codec the stream node announces on video/params (switched when it changes; "
        "nothing subscribed until it is heard), jpeg = image_raw/compressed, h264 = image_raw/ffmpeg",
        choices=INPUTS,
        read_only=True,
    ),
)


class RepublishNode(Node):
    """Decode the stream's JPEG or H.264 to bgr8 images, only on demand."""

    def __init__(self, name: str = "axis_republish", **kwargs: Any) -> None:
        """``kwargs`` go to :class:`rclpy.node.Node` (``context=``, ``parameter_overrides=``, ``namespace=``)."""
        super().__init__(name, **kwargs)
        self._live = LiveParams(self, PARAMS, on_change=lambda _names: self._update())  # lazy: live
        self._receiver: AccessUnitReceiver | None = None
        self._sub: Subscription | None = None
        self._sub_codec = ""  # the codec of _sub
        self._no_pyav = False  # H.264 cannot be decoded here: the JPEG topic instead (logged once)
        self.decoded = 0
        self.failed = 0
        events = PublisherEventCallbacks(matched=lambda _info: self._update())
        self._pub = publisher(self, Image, "image_raw", STREAM_QOS, event_callbacks=events)
        choice = str(self._live.params["input"])
        self.follower = follow_stream_codec(self, "mjpeg" if choice == "jpeg" else choice, lambda _c: self._update())
        self._timer = self.create_timer(0.1, self._update)
        self._update()

    @property
    def subscribed(self) -> bool:
        """Whether a video topic (JPEG or H.264) is subscribed right now."""
        return self._sub is not None

    @property
    def codec(self) -> str:
        """The video decoded while someone watches: ``mjpeg``, ``h264``, or ``""`` (none: waiting for
        ``video/params``)."""
        codec = self.follower.codec
        return "mjpeg" if codec == "h264" and self._no_pyav else codec

    def _update(self) -> None:
        codec = self.codec
        want = bool(codec) and (not self._live.params["lazy"] or self._pub.get_subscription_count() > 0)
        if self._sub is not None and (not want or self._sub_codec != codec):
            self.destroy_subscription(self._sub)  # the stream's codec changed, or nobody watches
            self._sub = None
            self._receiver = None
        if not want or self._sub is not None:
            return
        if codec == "h264":
            try:
                self._receiver = AccessUnitReceiver()  # a new subscription waits for an IDR
            except PyAvUnavailableError as err:
                self.get_logger().error(f"{err}; republishing the MJPEG topic image_raw/compressed instead")
                self._no_pyav = True
                self._update()
                return
            self._sub = self.create_subscription(
                FFMPEGPacket, "image_raw/ffmpeg", self._on_packet, VIDEO_QOS, event_callbacks=no_events()
            )
        else:
            self._sub = self.create_subscription(
                CompressedImage, "image_raw/compressed", self._on_compressed, STREAM_QOS, event_callbacks=no_events()
            )
        self._sub_codec = codec

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
