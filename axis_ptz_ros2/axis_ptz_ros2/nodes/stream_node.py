"""The stream node: the camera's video as ``image_raw/compressed`` + ``camera_info``, and H.264.

ROS glue over one ROS-free :class:`~axis_ptz_ros2.streaming.pipeline.VideoPipeline` (discovery, the MJPEG reader,
the MJPEG share, the RTSP source, the H.264 stage and the video controller, the one owner of the video parameters
in effect). The node declares its parameters, forwards their changes, consumers' reports and its subscriber counts
to the pipeline, and publishes what the pipeline hands it through one callback, ``_on_frame`` (an
:class:`~axis_ptz_ros2.media.frame.EncodedFrame` and the outlets it goes to), on the thread that made it. JPEGs go
out byte-for-byte as the camera sent them, stamped at arrival; ``camera_info`` goes with every main-stream JPEG
(size from the JPEG's SOF header, K from the camera model at the zoom reported on ``ptz/state`` or the ``zoom``
parameter), built once per (size, zoom) and only restamped (:mod:`~axis_ptz_ros2.nodes.stream_camera_info`). The
parameter table is :mod:`~axis_ptz_ros2.nodes.stream_params`.

Video parameters (``fps``, ``resolution``, ``compression``, ``max_bitrate_kbps`` …) are live
(:class:`~axis_ptz_ros2.nodes.live_params.LiveParams`): the candidate snapshot is validated as a whole in the
on-set callback (never sent to the camera when invalid), applied after the set (the reader reconnects with the
new request). ``video/set_params`` sets several atomically. ``video/params`` (latched)
carries what is in effect after every change, including those of the bandwidth budget.

Lazy by default: no HTTP request at all while nobody subscribes to ``image_raw/compressed``, ``camera_info``
or (with ``codec`` = ``h264``) the H.264 topics.

H.264 (``codec`` = ``h264``): a camera that streams H.264 (``Properties.Image.Format``) has its own RTSP stream
passed through, not re-encoded (:mod:`~axis_ptz_ros2.streaming.rtsp_source`, port ``rtsp_port``, stamped with the
camera's capture time); for one that does not (the 214), :class:`~axis_ptz_ros2.streaming.h264.H264Stage` turns its
JPEGs (asked for at compression 0) into H.264. Either way one H.264 stream is shared by ``image_raw/ffmpeg``
(``FFMPEGPacket``) and ``image_raw/foxglove`` (``CompressedVideo``): the same bytes, one access unit per message,
stamped with the frame's capture time; read or encoded only while one of them has a subscriber. A new subscriber
(with start points repeated for it, :mod:`~axis_ptz_ros2.streaming.start_points`), a reconnect, or a consumer's
report of decode errors on ``video/feedback`` asks for an IDR (from the camera: RTSP ``Renew-Stream``). Then
``image_raw/compressed`` comes from a second camera stream in a share of the budget, never the encoder's
compression-0 JPEGs (:mod:`~axis_ptz_ros2.streaming.mjpeg_share`), and consumers' reports about it do not judge the
link (the H.264 consumers' do).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from ffmpeg_image_transport_msgs.msg import FFMPEGPacket
from foxglove_msgs.msg import CompressedVideo
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_service import ParameterService
from rclpy.publisher import Publisher
from sensor_msgs.msg import CompressedImage

from axis_ptz_interfaces.msg import LinkFeedback
from axis_ptz_interfaces.msg import VideoParams as VideoParamsMsg
from axis_ptz_interfaces.srv import SetVideoParams
from axis_ptz_ros2.camera_models import CameraProfile, load_generic_base
from axis_ptz_ros2.config import CameraModel, load_camera_model
from axis_ptz_ros2.media.errors import EncoderError
from axis_ptz_ros2.media.frame import H264, EncodedFrame
from axis_ptz_ros2.nodes.common import (
    FEEDBACK_QOS,
    LATCHED_QOS,
    STREAM_QOS,
    VIDEO_QOS,
    camera_config_from_params,
    diagnostic,
    jpeg_format,
    publisher,
    stamp_from_ns,
)
from axis_ptz_ros2.nodes.live_params import LiveParams, Params
from axis_ptz_ros2.nodes.runner import run_nodes
from axis_ptz_ros2.nodes.stream_camera_info import CameraInfoOutput
from axis_ptz_ros2.nodes.stream_params import PARAMS
from axis_ptz_ros2.nodes.stream_still import StillOutput
from axis_ptz_ros2.streaming import ReaderConfig
from axis_ptz_ros2.streaming.discovery import camera_model_path
from axis_ptz_ros2.streaming.feedback import FeedbackReport
from axis_ptz_ros2.streaming.h264 import FFMPEG_ENCODING
from axis_ptz_ros2.streaming.pipeline import Outlet, VideoPipeline
from axis_ptz_ros2.streaming.status import LogLine, diagnostic_status
from axis_ptz_ros2.streaming.video_request import requested_changes
from axis_ptz_ros2.streaming.video_types import VideoSettings
from axis_ptz_ros2.vapix import VapixClient

__all__ = ["PARAMS", "StreamNode", "main"]


class StreamNode(Node):
    """``axis_stream``: the video pipeline's frames on ``image_raw/compressed`` + ``camera_info`` and the H.264
    topics, live video parameters, diagnostics.

    Its video publishers are made before its parameter services (rclpy would start those first): a participant sends
    a newcomer its endpoints' discovery data in the order they were made, one reliable stream, and a packet lost on a
    lossy link holds up everything after it until Fast DDS's discovery heartbeat a second later. First, a viewer
    learns of the video sooner (two-host bench, 2 Mbit/s + 2 %: see docs/weak-link.md, "First picture")."""

    def __init__(self, name: str = "axis_stream", **kwargs: Any) -> None:
        """``kwargs`` go to :class:`rclpy.node.Node` (``context=``, ``parameter_overrides=``, ``namespace=``)."""
        services = bool(kwargs.pop("start_parameter_services", True))
        super().__init__(name, start_parameter_services=False, **kwargs)  # started after the video publishers
        # validated as a whole before a set, applied after it (the pipeline exists by then: no set during __init__)
        self._live = LiveParams(self, PARAMS, validate=self._validate_params, on_change=self._apply_params)
        p = self._live.params
        self._frame_id = frame_id = str(p["frame_prefix"]) + str(p["frame_id"])
        model_file = camera_model_path(str(p["camera_model"])) or ""
        self._pending_source = "parameter"
        self._client = VapixClient(
            camera_config_from_params(p, timeout_s=max(float(p["read_timeout"]), float(p["connect_timeout"])))
        )

        # publishers (the hot path reuses one message of each kind: only the thread that made a frame publishes it)
        events = PublisherEventCallbacks(matched=lambda _info: self._update_activity())
        self._image_pub = publisher(self, CompressedImage, "image_raw/compressed", STREAM_QOS, event_callbacks=events)
        self._image_msg = CompressedImage()
        self._image_msg.header.frame_id = frame_id
        self._share_msg = CompressedImage()  # the MJPEG share's reader thread's own
        self._share_msg.header.frame_id = frame_id
        self._ffmpeg_pub = publisher(self, FFMPEGPacket, "image_raw/ffmpeg", VIDEO_QOS, event_callbacks=events)
        self._foxglove_pub = publisher(self, CompressedVideo, "image_raw/foxglove", VIDEO_QOS, event_callbacks=events)
        self._ffmpeg_msg = FFMPEGPacket(encoding=FFMPEG_ENCODING, is_bigendian=False)
        self._ffmpeg_msg.header.frame_id = frame_id
        self._foxglove_msg = CompressedVideo(format="h264", frame_id=frame_id)
        self._ffmpeg_wanted = self._foxglove_wanted = False
        self._params_pub = publisher(self, VideoParamsMsg, "video/params", LATCHED_QOS)
        self._diag_pub = publisher(self, DiagnosticArray, "/diagnostics", 10)
        if services:  # after the video publishers: see the class docstring
            self._parameter_service = ParameterService(self)

        self._pipeline = VideoPipeline(  # raises ValueError (start-up error) if the request is invalid
            self._client,
            self._live.config(VideoSettings),
            self._live.config(ReaderConfig),
            camera=int(p["camera"]),
            model_file=model_file,
            rtsp_port=int(p["rtsp_port"]),
            lazy=bool(p["lazy"]),
            on_frame=self._on_frame,
            on_params=self._publish_params,
            on_profile=self._on_profile,
            log=self._log,
        )
        pl = self._pipeline
        # its parts, for diagnostics and tests
        self._video, self._reader, self._stage, self._rtsp = pl.video, pl.reader, pl.stage, pl.rtsp
        res = lambda: self._video.current.resolution  # noqa: E731
        self._camera_info = CameraInfoOutput(  # camera_info, its zoom (ptz/state), camera_info_url, set_camera_info
            self,
            # until the camera has said what it is: the named file, else the generic model (replaced on discovery)
            load_camera_model(model_file) if model_file else load_generic_base(),
            frame_id,
            float(p["zoom"]),
            (str(p["camera_info_url"]), str(p["camera_name"])),
            lambda: (res().width, res().height),
            events=events,
        )
        # still/capture -> still/compressed: the camera's best JPEG on demand, counted against the budget
        self._still = StillOutput(
            self,
            self._client,
            self._video,
            frame_id,
            self.get_logger().warning,
            count=pl.on_still,
            crossed=pl.still_crossed,
        )

        self.feedback_reports = 0  # consumers' reports received (diagnostics, tests)
        self.create_subscription(LinkFeedback, "video/feedback", self._on_feedback, FEEDBACK_QOS)
        self.create_service(SetVideoParams, "video/set_params", self._on_set_video_params)
        self._publish_params()
        pl.start()
        self._update_activity()
        # Activity follows publisher-matched events at once; this 1 Hz timer is only the fallback poll,
        # the byte-trickle watchdog (a silent socket is caught by the read timeout) and diagnostics.
        self._timer = self.create_timer(1.0, self._housekeeping)

    @property
    def camera_model(self) -> CameraModel:
        """The camera model in use (the configured or generic one until the camera has said what it is)."""
        return self._camera_info.model

    def zoom_sink(self) -> Callable[[float], None]:
        """``camera_info``'s zoom fed by a PTZ node in this process instead of ``ptz/state`` (``axis_camera``)."""
        return self._camera_info.direct_zoom()

    # -- parameters ------------------------------------------------------------------------------------------
    @property
    def live_params(self) -> LiveParams:
        """The node's parameters: ``.params`` is the snapshot in effect (what ``ros2 param get`` tells)."""
        return self._live

    def _validate_params(self, candidate: Params, names: frozenset[str]) -> str | None:
        """on-set, the candidate as a whole: what rclpy's descriptors cannot check (the H.264 settings together,
        the resolution against the camera's list)."""
        try:
            settings = self._live.config(VideoSettings, candidate)
        except EncoderError as err:  # H264Settings checks its fields when made
            return str(err)
        return self._pipeline.check(settings, names)

    def _apply_params(self, names: frozenset[str]) -> None:
        """post-set (the snapshot swapped): the pipeline takes the new settings (its readers follow), the node its
        own."""
        p = self._live.params
        if "zoom" in names:
            self._camera_info.set_zoom_param(float(p["zoom"]))
        self._pipeline.apply(self._live.config(VideoSettings), names, self._pending_source, bool(p["lazy"]))
        if names & {"lazy", "codec"}:
            self._update_activity()

    def _on_set_video_params(
        self, request: SetVideoParams.Request, response: SetVideoParams.Response
    ) -> SetVideoParams.Response:
        """Set several video parameters at once: all or nothing (the parameter callbacks validate)."""
        changes = requested_changes(
            request.fps,
            request.resolution,
            request.compression,
            request.h264_bitrate_kbps,
            request.h264_max_bitrate_kbps,
        )
        if changes:
            self._pending_source = "service"
            try:
                result = self.set_parameters_atomically([Parameter(k, value=v) for k, v in changes.items()])
            finally:
                self._pending_source = "parameter"
            response.success = bool(result.successful)
            response.message = "" if result.successful else result.reason
        else:
            response.success = True
            response.message = "nothing to change"
        response.params = self._params_msg("service")
        return response

    def _params_msg(self, source: str | None = None) -> VideoParamsMsg:
        """The parameters in effect (after the bandwidth budget), as a message."""
        state = self._video.state()
        vp = state.params
        msg = VideoParamsMsg()
        msg.header.stamp = self.get_clock().now().to_msg()
        msg.header.frame_id = self._frame_id
        msg.fps = vp.fps
        msg.resolution = str(vp.resolution)
        msg.width, msg.height = vp.resolution.width, vp.resolution.height
        msg.compression = vp.compression
        msg.max_bitrate_kbps = int(state.budget_kbps)
        msg.source = source or state.source
        msg.available_resolutions = [str(r) for r in state.resolutions]
        settings = self._video.settings
        msg.codec = "h264" if self._video.h264 else "mjpeg"  # in effect (h264 asked without a way to make it: mjpeg)
        msg.h264_bitrate_kbps = settings.h264.bitrate_kbps
        msg.h264_max_bitrate_kbps = settings.h264.max_bitrate_kbps
        return msg

    def _publish_params(self) -> None:
        """What is in effect changed (any thread): ``video/params`` tells."""
        self._params_pub.publish(self._params_msg())

    # -- frames (the reader, MJPEG share and RTSP threads), the camera (discovery thread) -------------------------
    def _on_profile(self, profile: CameraProfile, first: bool) -> None:
        self._camera_info.set_model(profile.model)
        if first:
            self.get_logger().info(profile.summary())

    def _on_frame(self, frame: EncodedFrame, outlets: Outlet) -> None:
        """Hot path: publish a frame the pipeline hands out where it says (JPEG: the camera's bytes and a restamped
        CameraInfo; H.264: the same bytes on both H.264 topics)."""
        stamp = stamp_from_ns(frame.stamp_ns)
        if frame.codec == H264:
            self._publish_h264(frame, stamp)
            return
        if outlets & (Outlet.IMAGE | Outlet.SHARE_IMAGE):
            # the main stream's and the share's reader threads each have their own message
            msg = self._share_msg if outlets & Outlet.SHARE_IMAGE else self._image_msg
            msg.header.stamp = stamp
            msg.format = jpeg_format(1 if frame.grey else 3)  # colour or greyscale, as compressed_image_transport
            # The rosidl setter would copy into an array.array; the C converter reads any buffer, so hand
            # it the immutable bytes as they are (the only copy is rclpy's serialisation).
            msg._data = frame.data  # noqa: SLF001
            self._image_pub.publish(msg)
        if outlets & Outlet.CAMERA_INFO:
            self._camera_info.publish(frame.width, frame.height, stamp)

    def _publish_h264(self, frame: EncodedFrame, stamp: Any) -> None:
        if self._ffmpeg_wanted:
            msg = self._ffmpeg_msg
            msg.header.stamp = stamp
            msg.width, msg.height = frame.width, frame.height
            msg.pts = frame.pts
            msg.flags = 1 if frame.keyframe else 0
            msg._data = frame.data  # noqa: SLF001 - as for the JPEGs: no copy into an array.array
            self._ffmpeg_pub.publish(msg)
        if self._foxglove_wanted:
            fox = self._foxglove_msg
            fox.timestamp = stamp
            fox._data = frame.data  # noqa: SLF001
            self._foxglove_pub.publish(fox)

    def _on_feedback(self, msg: LinkFeedback) -> None:
        """A consumer's report: what it receives, judged by the controller against what was sent."""
        self.feedback_reports += 1
        report = FeedbackReport(
            consumer=str(msg.consumer),
            frames=int(msg.frames),
            fps=float(msg.fps),
            kbps=float(msg.kbps),
            delay_p95_s=float(msg.delay_p95_s),
            delay_p50_s=float(msg.delay_p50_s),
            delay_floor_s=float(msg.delay_floor_s),
            delay_min_s=float(msg.delay_min_s),
            gap_s=float(msg.gap_s),
            window_s=float(msg.window_s) if msg.window_s > 0 else 1.0,
            lost=int(msg.lost),
        )
        topic = str(msg.header.frame_id)
        about_h264 = not topic or any(names_topic(topic, pub.topic_name) for pub in self._h264_pubs)
        about_mjpeg = names_topic(topic, self._image_pub.topic_name)
        line = self._pipeline.on_report(report, int(msg.decode_errors), about_h264, about_mjpeg, self._subscribed)
        if line is not None:
            self.get_logger().debug(line)

    @property
    def _h264_pubs(self) -> tuple[Publisher, Publisher]:
        return self._ffmpeg_pub, self._foxglove_pub

    def _subscribed(self, consumer: str) -> bool:
        """Whether the node named ``consumer`` (fully qualified) has a discovered image subscription (in h264 mode
        also on the H.264 topics)."""
        pubs = [self._image_pub, *self._h264_pubs] if self._video.h264 else [self._image_pub]
        return consumer in self._subscriber_nodes(pubs)

    def _subscriber_nodes(self, pubs: list[Publisher]) -> frozenset[str]:
        names = set()
        for pub in pubs:
            for info in self.get_subscriptions_info_by_topic(pub.topic_name):
                names.add(f"{info.node_namespace.rstrip('/')}/{info.node_name}")
        return frozenset(names)

    # -- activity, watchdog, diagnostics (1 Hz) ------------------------------------------------------------------
    def _update_activity(self) -> None:
        """The subscriber counts to the pipeline (on matched events and at 1 Hz: no rmw call per frame)."""
        pipeline = getattr(self, "_pipeline", None)
        if pipeline is None:
            return
        ffmpeg = self._ffmpeg_pub.get_subscription_count()
        foxglove = self._foxglove_pub.get_subscription_count()
        self._ffmpeg_wanted, self._foxglove_wanted = ffmpeg > 0, foxglove > 0
        pipeline.set_demand(
            self._image_pub.get_subscription_count(),
            self._camera_info.pub.get_subscription_count(),
            ffmpeg + foxglove,
            lambda: self._subscriber_nodes(list(self._h264_pubs)),
        )

    def _housekeeping(self) -> None:
        self._update_activity()
        self._pipeline.tick()
        self._publish_diagnostics()

    def _log(self, line: LogLine) -> None:
        """A line of the pipeline's (throttled there)."""
        logger = self.get_logger()
        # One call site per severity: rclpy refuses a second severity from the same caller line.
        if line.level == "debug":
            logger.debug(line.text)
        elif line.level == "info":
            logger.info(line.text)
        elif line.level == "warn":
            logger.warning(line.text)
        else:
            logger.error(line.text)

    def _publish_diagnostics(self) -> None:
        stats = self._reader.stats()
        rate = self._reader.meter.rate(time.monotonic())
        extra: dict[str, object] = {**self._client.auth_counters.as_dict(), **self._pipeline.diagnostics()}
        level, message, values = diagnostic_status(stats, rate, self._video.state(), extra)
        name = f"{self.get_fully_qualified_name()}: MJPEG stream"
        self._diag_pub.publish(diagnostic(self, name, level, message, values, hardware_id=self._client.config.base_url))

    def destroy_node(self) -> None:
        """Stop and join the pipeline's threads (closing the streams from outside) and the still's, then the node."""
        pipeline = getattr(self, "_pipeline", None)
        if pipeline is not None:
            pipeline.stop(1.5)
        still = getattr(self, "_still", None)
        if still is not None:
            still.close(1.5)
        client = getattr(self, "_client", None)
        if client is not None:
            client.close()
        super().destroy_node()


def names_topic(name: str, topic: str) -> bool:
    """Whether a report's topic ``name`` (as the consumer wrote it: relative or absolute) is ``topic``
    (fully qualified)."""
    return bool(name) and (name == topic or topic.endswith("/" + name.lstrip("/")))


def main(args: list[str] | None = None) -> int:
    """``axis_stream``: the stream node on its own."""
    return run_nodes([StreamNode], args)


if __name__ == "__main__":
    raise SystemExit(main())
