"""The stream node's H.264 side (``codec`` = ``h264``): ``image_raw/ffmpeg`` and ``image_raw/foxglove``.

One :class:`~axis_ptz_ros2.streaming.h264.H264Stage` makes the access units; they come from the camera's own RTSP
stream when it streams H.264 (:func:`~axis_ptz_ros2.streaming.rtsp_source.passthrough_source`, passed through as
they are) or from the node's JPEGs, transcoded (the 214). Both topics carry the same bytes, one access unit per
message, stamped with the frame's capture time; nothing is read or encoded while neither has a subscriber. A new
subscriber, a reconnect, or a consumer's report of decode errors asks for an IDR. ROS glue: what to encode and
when is the stage's, the source's and the video controller's.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import replace
from typing import Any

from ffmpeg_image_transport_msgs.msg import FFMPEGPacket
from foxglove_msgs.msg import CompressedVideo
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.node import Node
from rclpy.publisher import Publisher

from axis_ptz_ros2.nodes.common import VIDEO_QOS, publisher, stamp_from_ns
from axis_ptz_ros2.streaming import ReaderConfig
from axis_ptz_ros2.streaming.controller import VideoController
from axis_ptz_ros2.streaming.h264 import FFMPEG_ENCODING, H264Stage, StagedFrame
from axis_ptz_ros2.streaming.passthrough_size import PassthroughSize
from axis_ptz_ros2.streaming.rtsp_source import passthrough_source
from axis_ptz_ros2.streaming.status import LogLine, h264_diagnostic_values, h264_mode_line
from axis_ptz_ros2.vapix import VapixClient
from axis_ptz_ros2.vapix.models import VideoParams


class H264Output:
    """The H.264 publishers, the stage that feeds them and the camera's RTSP source (see the module docstring).

    :attr:`transcode` (read on the frame path): the node's JPEGs feed the stage (``codec`` h264, someone
    subscribes, and the camera cannot stream H.264 itself)."""

    def __init__(
        self,
        node: Node,
        client: VapixClient,
        video: VideoController,
        reader_config: ReaderConfig,
        rtsp_port: int,
        frame_id: str,
        *,
        events: PublisherEventCallbacks,
        log: Callable[[LogLine], None],
        on_supported: Callable[[], None],
    ) -> None:
        """``log``: throttled warnings of the stage and the RTSP source; ``on_supported()``: the camera has said
        whether it streams H.264 (activity may change)."""
        self._node = node
        self._video = video
        self.ffmpeg_pub: Publisher = publisher(
            node, FFMPEGPacket, "image_raw/ffmpeg", VIDEO_QOS, event_callbacks=events
        )
        self.foxglove_pub: Publisher = publisher(
            node, CompressedVideo, "image_raw/foxglove", VIDEO_QOS, event_callbacks=events
        )
        # the hot path reuses one message of each kind: only the reader (or RTSP) thread publishes them
        self._ffmpeg_msg = FFMPEGPacket(encoding=FFMPEG_ENCODING, is_bigendian=False)
        self._ffmpeg_msg.header.frame_id = frame_id
        self._foxglove_msg = CompressedVideo(format="h264", frame_id=frame_id)
        self.subscribers = 0  # on the two H.264 topics, at the last update
        self._ffmpeg_wanted = self._foxglove_wanted = False
        self.stage = H264Stage(
            video.h264_settings, self._publish, on_problem=lambda text: log(LogLine("warn", text, "h264", 10.0))
        )
        self._told_mode = False
        self.transcode = False  # codec h264 from a camera that cannot stream it: the MJPEG feeds the stage
        self.size = PassthroughSize()  # the size the camera's own H.264 is asked for with resolution auto
        self.rtsp = passthrough_source(  # codec h264 from a camera that streams it: its own H.264, as it is
            client,
            rtsp_port,
            self._passthrough_params,
            video.h264_settings,
            self.stage,
            reader_config,
            on_supported=lambda _ok: on_supported(),
            on_event=lambda text: log(LogLine("warn", text, "rtsp", 10.0)),
        )

    def _passthrough_params(self) -> VideoParams:
        """What the camera's own H.264 is asked for (RTSP thread, every access unit): the parameters in effect; with
        ``resolution`` auto and the camera's sizes known, at the size that reads best at the bitrate in force
        (:class:`~axis_ptz_ros2.streaming.passthrough_size.PassthroughSize`), shown on ``video/params``."""
        video = self._video
        params = video.current
        if str(video.settings.resolution).strip() or not video.resolutions_known:
            video.set_stream_size(None)  # an explicit size is asked for as it is
            return params
        kbps = video.h264_settings().bitrate_kbps
        size = self.size.update(time.monotonic(), video.state().resolutions, params.resolution, params.fps, kbps)
        video.set_stream_size(size)
        return replace(params, resolution=size)

    @property
    def publishers(self) -> tuple[Publisher, Publisher]:
        """The two H.264 publishers."""
        return self.ffmpeg_pub, self.foxglove_pub

    def update(self) -> bool:
        """Follow the subscriber counts (an IDR for a new viewer); return :attr:`transcode`."""
        ffmpeg = self.ffmpeg_pub.get_subscription_count()
        foxglove = self.foxglove_pub.get_subscription_count()
        self._ffmpeg_wanted, self._foxglove_wanted = ffmpeg > 0, foxglove > 0
        h264 = ffmpeg + foxglove
        if h264 > self.subscribers:
            self.stage.new_subscriber()  # a new viewer needs a start point
        self.subscribers = h264
        encode = self._video.h264 and h264 > 0
        supported = self.rtsp.supported  # None until asked (on the first activation)
        self.transcode = encode and supported is False
        if encode and supported is not None and not self._told_mode:
            self._told_mode = True
            self._node.get_logger().info(h264_mode_line(supported))
        self.stage.set_active(encode)
        self.rtsp.set_active(encode)
        return self.transcode

    def on_jpeg(self, jpeg: bytes, arrival_ns: int) -> None:
        """A camera JPEG (reader thread): encoded when transcoding (pass-through: the RTSP source feeds the stage)."""
        if self.transcode:
            self.stage.on_jpeg(jpeg, arrival_ns)

    def on_reconnected(self) -> None:
        """The MJPEG stream (re)connected: an IDR first (pass-through: the RTSP session starts with its own)."""
        if self.transcode:
            self.stage.discontinuity()

    def on_decode_errors(self, consumer: str, errors: int) -> None:
        """A consumer's count of access units it could not show (its report's window): when it grew (new
        losses), a start point now, not at the next periodic IDR (:meth:`H264Stage.consumer_errors`)."""
        if self.stage.active:
            self.stage.consumer_errors(consumer, errors)

    def _publish(self, frame: StagedFrame) -> None:
        """One access unit (reader or RTSP thread): the same bytes on both H.264 topics."""
        stamp = stamp_from_ns(frame.stamp_ns)
        if self._ffmpeg_wanted:
            msg = self._ffmpeg_msg
            msg.header.stamp = stamp
            msg.width, msg.height = frame.width, frame.height
            msg.pts = frame.pts
            msg.flags = 1 if frame.keyframe else 0
            msg._data = frame.data  # noqa: SLF001 - as for the JPEGs: no copy into an array.array
            self.ffmpeg_pub.publish(msg)
        if self._foxglove_wanted:
            fox = self._foxglove_msg
            fox.timestamp = stamp
            fox._data = frame.data  # noqa: SLF001
            self.foxglove_pub.publish(fox)
        self._video.on_h264_frame(time.monotonic(), len(frame.data))

    def diagnostics(self) -> dict[str, Any]:
        """The H.264 side's diagnostics values."""
        bitrate = self._video.h264_settings().bitrate_kbps
        s = self._video.settings
        return h264_diagnostic_values(
            self.stage.active,
            bitrate,
            self.stage.stats,
            self.rtsp.stats,
            self.rtsp.supported,
            int(s.h264_bitrate_kbps),
            int(s.h264_max_bitrate_kbps),
        )

    def start(self) -> None:
        """Start the RTSP source (it stays idle until :meth:`update` activates it)."""
        self.rtsp.start()

    def stop(self, timeout_s: float) -> None:
        """Stop and join the RTSP source."""
        self.rtsp.stop(timeout_s)
