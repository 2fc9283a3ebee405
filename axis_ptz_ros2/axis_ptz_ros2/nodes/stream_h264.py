"""The stream node's H.264 side (``codec`` = ``h264``): ``image_raw/ffmpeg`` and ``image_raw/foxglove``.

One :class:`~axis_ptz_ros2.streaming.h264.H264Stage` makes the access units; they come from the camera's own RTSP
stream when it streams H.264 (:func:`~axis_ptz_ros2.streaming.rtsp_source.passthrough_source`, passed through as
they are) or from the node's JPEGs, transcoded (the 214). Both topics carry the same bytes, one access unit per
message, stamped with the frame's capture time; nothing is read or encoded while neither has a subscriber. A new
subscriber, a reconnect, or a consumer's report of decode errors asks for an IDR. ROS glue: what to encode and
when is the stage's, the source's and the video controller's.

A start point for every viewer (issue 40): with intra refresh the only IDRs are those asked for, and a viewer that
sends no feedback (``rqt_image_view``, a plain subscription) asks only by appearing. The stage sends it two (at once
and 0.4 s later); on a crowded link the keep-last-4 queue can replace both before they are repaired, and the viewer
then waits forever (issue 40: 331 access units in 20 s, none an IDR). So a new subscriber is also sent an IDR at
each of :data:`START_IDR_REPEATS_S` after it appeared, unless every H.264 subscriber has by then reported on
``video/feedback`` that it shows pictures (frames, no decode errors: it has had a start point); a consumer that
does report asks for more itself through its decode errors.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import replace
from typing import Any, Final

from ffmpeg_image_transport_msgs.msg import FFMPEGPacket
from foxglove_msgs.msg import CompressedVideo
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.node import Node
from rclpy.publisher import Publisher

from axis_ptz_ros2.nodes.common import VIDEO_QOS, publisher, stamp_from_ns
from axis_ptz_ros2.streaming import ReaderConfig
from axis_ptz_ros2.streaming.controller import VideoController
from axis_ptz_ros2.media.frame import EncodedFrame
from axis_ptz_ros2.streaming.h264 import FFMPEG_ENCODING, H264Stage
from axis_ptz_ros2.streaming.passthrough_size import PassthroughSize
from axis_ptz_ros2.streaming.rtsp_source import passthrough_source
from axis_ptz_ros2.streaming.status import LogLine, h264_diagnostic_values, h264_mode_line
from axis_ptz_ros2.vapix import VapixClient
from axis_ptz_ros2.vapix.models import VideoParams

#: s after a new H.264 subscriber appeared: further IDRs for it (see the module docstring). The first within the
#: 2 s a viewer's first picture may take, the last ~5 s of congestion out; at least 1.2 s apart so that an intra
#: refresh wave (one per second of frames) still begins between them, and each costs one squeezed picture
START_IDR_REPEATS_S: Final = (1.2, 2.4, 4.8)


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
        self._lock = threading.Lock()
        self._repeats: deque[float] = deque()  # when the next start-point IDRs are due (monotonic)
        self._viewers: frozenset[str] = frozenset()  # the H.264 subscribers' nodes (fully qualified)
        self._showing: set[str] = set()  # consumers whose last H.264 report shows pictures without errors
        self.start_repeats = 0  # start-point IDRs asked for by the repeats
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
            now = time.monotonic()
            with self._lock:
                self._viewers = self._subscriber_nodes()
                self._repeats = deque(now + t for t in START_IDR_REPEATS_S)
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

    def on_report(self, consumer: str, topic: str, frames: int, errors: int) -> None:
        """A consumer's report on ``video/feedback`` about ``topic`` (the name it wrote): its count of access units
        it could not show (its report's window), when it grew (new losses), asks for a start point now
        (:meth:`H264Stage.consumer_errors`); pictures without errors on an H.264 topic mean it has had one."""
        if topic and not any(names_topic(topic, pub.topic_name) for pub in self.publishers):
            return  # about another topic (the MJPEG share): says nothing of the H.264 stream (no topic: taken as H.264)
        with self._lock:
            if frames > 0 and errors == 0:
                self._showing.add(consumer)
            else:
                self._showing.discard(consumer)
        if self.stage.active:
            self.stage.consumer_errors(consumer, errors)

    def _subscriber_nodes(self) -> frozenset[str]:
        names = set()
        for pub in self.publishers:
            for info in self._node.get_subscriptions_info_by_topic(pub.topic_name):
                names.add(f"{info.node_namespace.rstrip('/')}/{info.node_name}")
        return frozenset(names)

    def _start_repeat_due(self, now: float) -> bool:
        """Whether a start-point IDR is due now (reader or RTSP thread; see the module docstring)."""
        if not self._repeats or now < self._repeats[0]:
            return False
        with self._lock:
            while self._repeats and now >= self._repeats[0]:
                self._repeats.popleft()
            if self._viewers and self._viewers <= self._showing:
                self._repeats.clear()  # every viewer has reported pictures: it has had its start point
                return False
        return True

    def _publish(self, frame: EncodedFrame) -> None:
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
        now = time.monotonic()
        self._video.on_h264_frame(now, len(frame.data))
        if self._start_repeat_due(now):
            self.start_repeats += 1
            self.stage.request_idr()

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


def names_topic(name: str, topic: str) -> bool:
    """Whether a report's topic ``name`` (as the consumer wrote it: relative or absolute) is ``topic``
    (fully qualified)."""
    return bool(name) and (name == topic or topic.endswith("/" + name.lstrip("/")))
