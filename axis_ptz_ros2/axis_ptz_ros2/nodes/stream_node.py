"""The stream node: the camera's Motion-JPEG stream as ``image_raw/compressed`` + ``camera_info``.

ROS glue over ROS-free parts: :class:`~axis_ptz_ros2.streaming.controller.VideoController` (the one owner of the
video parameters in effect: request, bandwidth budget, link adaptation, the camera's sizes),
:class:`~axis_ptz_ros2.streaming.reader.StreamReader` (the one reader thread) and
:class:`~axis_ptz_ros2.streaming.discovery.CameraDiscovery` (what the camera is; its stream). Frames are published
*from the reader thread*, byte-for-byte as the camera sent them, stamped at arrival; ``camera_info`` goes with
every frame (size from the JPEG's SOF header, K from the camera model at the zoom reported on ``ptz/state`` or
the ``zoom`` parameter), built once per (size, zoom) and only restamped
(:mod:`~axis_ptz_ros2.nodes.stream_camera_info`). The parameter table is :mod:`~axis_ptz_ros2.nodes.stream_params`.

Video parameters (``fps``, ``resolution``, ``compression``, ``max_bitrate_kbps`` …) are live
(:class:`~axis_ptz_ros2.nodes.live_params.LiveParams`): the candidate snapshot is validated as a whole in the
on-set callback (never sent to the camera when invalid), applied after the set (the reader reconnects with the
new request). ``video/set_params`` sets several atomically. ``video/params`` (latched)
carries what is in effect after every change, including those of the bandwidth budget.

Lazy by default: no HTTP request at all while nobody subscribes to ``image_raw/compressed``, ``camera_info``
or (with ``codec`` = ``h264``) the H.264 topics.

H.264 (``codec`` = ``h264``, :mod:`~axis_ptz_ros2.nodes.stream_h264`): a camera that streams H.264
(``Properties.Image.Format``) has its own RTSP stream passed through, not re-encoded
(:mod:`~axis_ptz_ros2.streaming.rtsp_source`, port ``rtsp_port``, stamped with the camera's capture time); for one
that does not (the 214), :class:`~axis_ptz_ros2.streaming.h264.H264Stage` turns its JPEGs (asked for at
compression 0) into H.264. Either way one H.264 stream is shared by ``image_raw/ffmpeg`` (``FFMPEGPacket``) and
``image_raw/foxglove`` (``CompressedVideo``): the same bytes, one access unit per message, stamped with the frame's
capture time; read or encoded only while one of them has a subscriber. A new subscriber, a reconnect, or a
consumer's report of decode errors on ``video/feedback`` asks for an IDR (from the camera: RTSP ``Renew-Stream``).
Then ``image_raw/compressed`` comes from a second camera stream in a share of the budget, never the encoder's
compression-0 JPEGs (:mod:`~axis_ptz_ros2.nodes.stream_mjpeg`), and consumers' reports about it do not judge the
link (the H.264 consumers' do).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import CompressedImage

from axis_ptz_interfaces.msg import LinkFeedback
from axis_ptz_interfaces.msg import VideoParams as VideoParamsMsg
from axis_ptz_interfaces.srv import SetVideoParams
from axis_ptz_ros2.camera_models import CameraProfile, load_generic_base
from axis_ptz_ros2.config import CameraModel, load_camera_model
from axis_ptz_ros2.nodes.common import (
    FEEDBACK_QOS,
    LATCHED_QOS,
    STREAM_QOS,
    camera_config_from_params,
    diagnostic,
    jpeg_format,
    publisher,
    stamp_from_ns,
)
from axis_ptz_ros2.nodes.live_params import LiveParams, Params
from axis_ptz_ros2.nodes.runner import run_nodes
from axis_ptz_ros2.nodes.stream_camera_info import CameraInfoOutput
from axis_ptz_ros2.nodes.stream_h264 import H264Output, names_topic
from axis_ptz_ros2.nodes.stream_mjpeg import MjpegShareOutput
from axis_ptz_ros2.nodes.stream_params import PARAMS
from axis_ptz_ros2.nodes.stream_still import StillOutput
from axis_ptz_ros2.streaming import BitrateMeter, ReaderConfig, StreamReader, StreamState
from axis_ptz_ros2.streaming.controller import VideoController, requested_changes
from axis_ptz_ros2.streaming.discovery import CameraDiscovery, camera_model_path
from axis_ptz_ros2.streaming.feedback import FeedbackReport
from axis_ptz_ros2.streaming.jpeg import jpeg_sof
from axis_ptz_ros2.streaming.status import LogLine, LogThrottle, diagnostic_status, reader_event_line
from axis_ptz_ros2.streaming.video_types import VideoSettings
from axis_ptz_ros2.vapix import VapixClient
from axis_ptz_ros2.vapix.models import VideoParams as CameraVideoParams

__all__ = ["PARAMS", "StreamNode", "main"]


class StreamNode(Node):
    """``axis_stream``: MJPEG → ``image_raw/compressed`` + ``camera_info``, live video parameters, diagnostics."""

    def __init__(self, name: str = "axis_stream", **kwargs: Any) -> None:
        """``kwargs`` go to :class:`rclpy.node.Node` (``context=``, ``parameter_overrides=``, ``namespace=``)."""
        super().__init__(name, **kwargs)
        # validated as a whole before a set, applied after it (the controller exists by then: no set during __init__)
        self._live = LiveParams(self, PARAMS, validate=self._validate_params, on_change=self._apply_params)
        p = self._live.params
        self._frame_id = str(p["frame_prefix"]) + str(p["frame_id"])
        model_file = camera_model_path(str(p["camera_model"])) or ""
        self._log_throttle = LogThrottle()
        reader_config = self._live.config(ReaderConfig)
        meter = BitrateMeter(reader_config.meter_window_s)
        self._video = VideoController(  # raises ValueError (start-up error) if the request is invalid
            self._live.config(VideoSettings), meter, camera=int(p["camera"]), on_change=self._publish_params
        )
        self._pending_source = "parameter"
        self._client = VapixClient(
            camera_config_from_params(p, timeout_s=max(float(p["read_timeout"]), float(p["connect_timeout"])))
        )
        self._discovery = CameraDiscovery(
            self._client,
            model_file,
            lambda: self._video.current,
            on_profile=self._on_profile,
            on_resolutions=self._video.learn_resolutions,
            on_problem=lambda text: self._log(LogLine("warn", text, "resolutions", 30.0)),
        )

        # publishers (the hot path reuses one message of each kind: only the reader thread publishes them)
        events = PublisherEventCallbacks(matched=lambda _info: self._update_activity())
        self._image_pub = publisher(self, CompressedImage, "image_raw/compressed", STREAM_QOS, event_callbacks=events)
        self._image_msg = CompressedImage()
        self._image_msg.header.frame_id = self._frame_id
        res = lambda: self._video.current.resolution  # noqa: E731
        self._camera_info = CameraInfoOutput(  # camera_info, its zoom (ptz/state), camera_info_url, set_camera_info
            self,
            # until the camera has said what it is: the named file, else the generic model (replaced on discovery)
            load_camera_model(model_file) if model_file else load_generic_base(),
            self._frame_id,
            float(p["zoom"]),
            (str(p["camera_info_url"]), str(p["camera_name"])),
            lambda: (res().width, res().height),
            events=events,
        )
        self._params_pub = publisher(self, VideoParamsMsg, "video/params", LATCHED_QOS)
        self._diag_pub = publisher(self, DiagnosticArray, "/diagnostics", 10)
        self._h264 = H264Output(
            self,
            self._client,
            self._video,
            reader_config,
            int(p["rtsp_port"]),
            self._frame_id,
            events=events,
            log=self._log,
            on_supported=self._update_activity,
        )
        self._stage, self._rtsp = self._h264.stage, self._h264.rtsp  # (statistics for tests and diagnostics)
        # h264 mode: image_raw/compressed from a second camera stream, in a share of the budget
        self._mjpeg = MjpegShareOutput(
            self._client,
            self._video,
            self._image_pub,
            self._frame_id,
            reader_config,
            reference=self._share_reference,
            on_event=self._on_share_event,
        )
        # still/capture -> still/compressed: the camera's best JPEG on demand, counted against the budget
        self._still = StillOutput(self, self._client, self._video, self._frame_id, self.get_logger().warning)

        self.feedback_reports = 0  # consumers' reports received (diagnostics, tests)
        self.create_subscription(LinkFeedback, "video/feedback", self._on_feedback, FEEDBACK_QOS)
        self.create_service(SetVideoParams, "video/set_params", self._on_set_video_params)
        self._lazy = bool(p["lazy"])
        self._image_wanted = False  # the main stream's JPEGs go on image_raw/compressed (codec mjpeg)
        self._info_wanted = False

        self._reader = StreamReader(
            self._discovery.open,
            self._on_frame,
            lambda: self._video.current,  # the controller owns the parameters; the reader follows
            reader_config,
            on_event=self._on_reader_event,
            active=self._want_active(),
            meter=meter,
        )
        self._publish_params()
        self._reader.start()
        self._mjpeg.start()
        self._h264.start()
        self._discovery.start()  # learn the camera even while nobody subscribes: video/params lists its sizes
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
        return self._video.check(self._live.config(VideoSettings, candidate), names)

    def _apply_params(self, names: frozenset[str]) -> None:
        """post-set (the snapshot swapped): hand the new settings to the controller (the reader follows), take the
        node's own."""
        p = self._live.params
        if "lazy" in names:
            self._lazy = bool(p["lazy"])
            self._update_activity()
        if "zoom" in names:
            self._camera_info.set_zoom_param(float(p["zoom"]))
        self._video.apply(self._live.config(VideoSettings), names, self._pending_source)
        if "codec" in names:
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
        msg.codec = str(settings.codec)
        msg.h264_bitrate_kbps = int(settings.h264_bitrate_kbps)
        msg.h264_max_bitrate_kbps = int(settings.h264_max_bitrate_kbps)
        return msg

    def _publish_params(self) -> None:
        """The controller's announcement (any thread): the reader follows, ``video/params`` tells."""
        reader = getattr(self, "_reader", None)
        if reader is not None:
            reader.refresh()
        self._params_pub.publish(self._params_msg())

    # -- camera and frames (reader and discovery threads) ----------------------------------------------------
    def _on_profile(self, profile: CameraProfile, first: bool) -> None:
        self._camera_info.set_model(profile.model)
        if first:
            self.get_logger().info(profile.summary())

    def _on_frame(self, jpeg: bytes, arrival_ns: int) -> None:
        """Hot path (reader thread): publish the camera's bytes and a restamped CameraInfo."""
        stamp = stamp_from_ns(arrival_ns)
        sof = jpeg_sof(jpeg) if self._image_wanted or self._info_wanted else None  # one walk of the header
        if self._image_wanted:
            msg = self._image_msg
            msg.header.stamp = stamp
            msg.format = jpeg_format(sof[2] if sof else 3)  # colour or greyscale, as compressed_image_transport
            # The rosidl setter would copy into an array.array; the C converter reads any buffer, so hand
            # it the immutable bytes as they are (the only copy is rclpy's serialisation).
            msg._data = jpeg  # noqa: SLF001
            self._image_pub.publish(msg)
        if self._info_wanted:
            if sof is None:
                res = self._video.current.resolution
                self._camera_info.publish(res.width, res.height, stamp)
            else:
                self._camera_info.publish(sof[0], sof[1], stamp)
        self._h264.on_jpeg(jpeg, arrival_ns)
        step = self._video.on_frame(time.monotonic())
        if step is not None:
            self.get_logger().debug(str(step))

    def _on_feedback(self, msg: LinkFeedback) -> None:
        """A consumer's report: what it receives, judged by the controller against what was sent."""
        self.feedback_reports += 1
        report = FeedbackReport(
            consumer=str(msg.consumer),
            frames=int(msg.frames),
            fps=float(msg.fps),
            kbps=float(msg.kbps),
            delay_p95_s=float(msg.delay_p95_s),
            delay_min_s=float(msg.delay_min_s),
            gap_s=float(msg.gap_s),
            window_s=float(msg.window_s) if msg.window_s > 0 else 1.0,
            lost=int(msg.lost),
        )
        topic = str(msg.header.frame_id)
        self._h264.on_report(str(msg.consumer), topic, int(msg.frames), int(msg.decode_errors))
        if self._video.h264 and names_topic(topic, self._image_pub.topic_name):
            return  # about the MJPEG share: the H.264 consumers' reports judge the link (their bytes are its bulk)
        judgement = self._video.feedback(report, self._subscribed)
        if judgement is not None:
            self.get_logger().debug(str(judgement))

    def _subscribed(self, consumer: str) -> bool:
        """Whether the node named ``consumer`` (fully qualified) has a discovered image subscription (in h264 mode
        also on the H.264 topics)."""
        pubs = [self._image_pub, *self._h264.publishers] if self._video.h264 else [self._image_pub]
        for pub in pubs:
            for info in self.get_subscriptions_info_by_topic(pub.topic_name):
                ns = info.node_namespace.rstrip("/")
                if f"{ns}/{info.node_name}" == consumer:
                    return True
        return False

    # -- activity, watchdog, diagnostics (1 Hz) ------------------------------------------------------------------
    def _want_active(self) -> bool:
        # Cached for the hot path (no rmw call per frame); refreshed on matched events and at 1 Hz.
        image = self._image_pub.get_subscription_count() > 0
        h264 = self._video.h264
        self._image_wanted = image and not h264
        self._info_wanted = self._camera_info.pub.get_subscription_count() > 0
        mjpeg = getattr(self, "_mjpeg", None)
        if mjpeg is not None:
            mjpeg.set_active(image and h264)
        transcode = self._h264.update()
        return not self._lazy or self._image_wanted or self._info_wanted or transcode

    def _share_reference(self) -> tuple[CameraVideoParams, float]:
        """The main stream's parameters and measured bytes a frame, the MJPEG share's first step is predicted from
        (0 while the reader is being built: a subscriber already there makes the share start during construction)."""
        reader = getattr(self, "_reader", None)
        bpf = reader.meter.rate(time.monotonic()).bytes_per_frame if reader is not None else 0.0
        return self._video.current, bpf

    def _update_activity(self) -> None:
        reader = getattr(self, "_reader", None)
        if reader is not None:
            reader.set_active(self._want_active())

    def _housekeeping(self) -> None:
        self._update_activity()
        self._reader.check_watchdog()
        self._video.tick()
        self._publish_diagnostics()

    def _log(self, line: LogLine) -> None:
        if not self._log_throttle.allow(line):
            return
        logger = self.get_logger()
        # One call site per severity: rclpy refuses a second severity from the same caller line.
        if line.level == "info":
            logger.info(line.text)
        elif line.level == "warn":
            logger.warning(line.text)
        else:
            logger.error(line.text)

    def _on_reader_event(self, state: StreamState, message: str) -> None:
        """Reader state changes and errors (reader thread); throttled so an absent camera is not spammed."""
        if state is StreamState.STREAMING:
            self._log_throttle.forget("reconnect")
            self._h264.on_reconnected()
        line = reader_event_line(state, message, self._video.current, self._reader.config.auth_retry_s)
        if line is not None:
            self._log(line)

    def _on_share_event(self, state: StreamState, message: str) -> None:
        """The MJPEG share's reader (h264 mode): its errors, throttled."""
        if message and state is not StreamState.STREAMING:
            self._log(LogLine("warn", f"MJPEG share stream ({state}): {message}", "mjpeg-share", 10.0))

    def _publish_diagnostics(self) -> None:
        stats = self._reader.stats()
        rate = self._reader.meter.rate(time.monotonic())
        extra: dict[str, object] = {**self._client.auth_counters.as_dict()}
        if self._video.h264:
            extra |= self._h264.diagnostics() | self._mjpeg.diagnostics()
        level, message, values = diagnostic_status(stats, rate, self._video.state(), extra)
        name = f"{self.get_fully_qualified_name()}: MJPEG stream"
        self._diag_pub.publish(diagnostic(self, name, level, message, values, hardware_id=self._client.config.base_url))

    def destroy_node(self) -> None:
        """Stop and join the reader thread (closing the stream from outside) and discovery, then the node."""
        discovery = getattr(self, "_discovery", None)
        if discovery is not None:
            discovery.stop(0.0)  # no new attempt from here on (joined below, once the reader has stopped)
        h264 = getattr(self, "_h264", None)
        if h264 is not None:
            h264.stop(1.5)
        mjpeg = getattr(self, "_mjpeg", None)
        if mjpeg is not None:
            mjpeg.stop(1.5)
        still = getattr(self, "_still", None)
        if still is not None:
            still.close(1.5)
        reader = getattr(self, "_reader", None)
        if reader is not None:
            reader.stop(1.5)
        if discovery is not None:
            discovery.stop(2.0)
        client = getattr(self, "_client", None)
        if client is not None:
            client.close()
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """``axis_stream``: the stream node on its own."""
    return run_nodes([StreamNode], args)


if __name__ == "__main__":
    raise SystemExit(main())
