"""The stream node's MJPEG topic while the codec is H.264: a second camera stream in a share of the budget.

While ``codec`` is ``h264`` the node's main stream is the camera's compression-0 JPEGs, the encoder's input; they
never go on ``image_raw/compressed`` (one of them is 1.96 Mbit at 704x576: a weak link carries one a second).
Instead, while that topic has a subscriber, this second reader streams from the camera with the parameters of
:class:`~axis_ptz_ros2.streaming.mjpeg_share.MjpegShare` (the MJPEG ladder in its share of the budget; why, with
the measurement, in that module) and publishes its JPEGs there, stamped at arrival like the main stream's.
``camera_info`` stays with the main stream (the size in ``video/params``, that of the H.264 topics); each JPEG here
carries its own size in its header. ROS glue.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from rclpy.publisher import Publisher
from sensor_msgs.msg import CompressedImage

from axis_ptz_ros2.nodes.common import jpeg_format, stamp_from_ns
from axis_ptz_ros2.streaming import ReaderConfig, StreamReader, StreamState
from axis_ptz_ros2.streaming.controller import VideoController
from axis_ptz_ros2.streaming.jpeg import jpeg_sof
from axis_ptz_ros2.vapix import VapixClient
from axis_ptz_ros2.vapix.models import VideoParams


class MjpegShareOutput:
    """The second MJPEG reader and what it publishes (see the module docstring)."""

    def __init__(
        self,
        client: VapixClient,
        video: VideoController,
        image_pub: Publisher,
        frame_id: str,
        reader_config: ReaderConfig,
        *,
        reference: Callable[[], tuple[VideoParams, float]],
        on_event: Callable[[StreamState, str], None],
    ) -> None:
        """``reference()``: the main stream's parameters and measured bytes per frame (its first level is
        predicted from them); ``on_event``: the reader's state changes and errors."""
        self._video = video
        self._share = video.mjpeg
        self._pub = image_pub
        self._reference = reference
        self._msg = CompressedImage()
        self._msg.header.frame_id = frame_id
        self.published = 0
        self.reader = StreamReader(
            lambda params, timeout: client.open_mjpeg(params, timeout),
            self._on_frame,
            lambda: self._share.current,
            reader_config,
            on_event=on_event,
            active=False,
            meter=self._share.meter,
        )

    def set_active(self, active: bool) -> None:
        """Run the second stream (codec h264 and a subscriber on the MJPEG topic) or stop it; the encoder's
        bitrate makes room for it (:meth:`VideoController.h264_settings`)."""
        if active == self._share.active:
            return
        if active:
            ref, bpf = self._reference()
            self._share.start(ref, bpf)
        self._share.active = active
        self.reader.refresh()
        self.reader.set_active(active)

    def _on_frame(self, jpeg: bytes, arrival_ns: int) -> None:
        """Hot path (the second reader's thread): publish the camera's bytes; the ladder judges the share."""
        msg = self._msg
        msg.header.stamp = stamp_from_ns(arrival_ns)
        sof = jpeg_sof(jpeg)
        msg.format = jpeg_format(sof[2] if sof else 3)
        msg._data = jpeg  # noqa: SLF001 - as the main stream: no copy into an array.array
        self._pub.publish(msg)
        self.published += 1
        if self._share.on_frame(time.monotonic()) is not None:
            self.reader.refresh()  # the ladder stepped: reconnect with its parameters

    def diagnostics(self) -> dict[str, object]:
        """The second stream's values (h264 mode)."""
        if not self._share.active:
            return {"mjpeg share": "off (no MJPEG subscriber)"}
        p = self._share.current
        rate = self._share.meter.rate(time.monotonic())
        return {
            "mjpeg share [kbit/s]": round(self._share.budget_kbps),
            "mjpeg share stream": f"{p.resolution} @ {p.fps} fps, compression {p.compression}",
            "mjpeg share sent [kbit/s]": round(rate.kbps),
        }

    def start(self) -> None:
        """Start the reader thread (idle until :meth:`set_active`)."""
        self.reader.start()

    def stop(self, timeout_s: float) -> None:
        """Stop and join the reader thread."""
        self.reader.stop(timeout_s)
