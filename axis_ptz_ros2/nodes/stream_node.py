"""The stream node: the camera's Motion-JPEG stream as ``image_raw/compressed`` + ``camera_info``.

ROS glue over ROS-free parts: :class:`~axis_ptz_ros2.streaming.controller.VideoController` (the one owner of the
video parameters in effect: request, bandwidth budget, link adaptation, the camera's sizes),
:class:`~axis_ptz_ros2.streaming.reader.StreamReader` (the one reader thread) and
:class:`~axis_ptz_ros2.streaming.discovery.CameraDiscovery` (what the camera is; its stream). Frames are published
*from the reader thread*, byte-for-byte as the camera sent them, stamped at arrival; ``camera_info`` goes with
every frame (size from the JPEG's SOF header, K from the camera model at the zoom reported on ``ptz/state`` or
the ``zoom`` parameter), built once per (size, zoom) and only restamped.

Video parameters (``fps``, ``resolution``, ``compression``, ``max_bitrate_kbps`` …) are live: validated in
the on-set callback (never sent to the camera when invalid), applied in the post-set callback (the reader
reconnects with the new request). ``video/set_params`` sets several atomically. ``video/params`` (latched)
carries what is in effect after every change, including those of the bandwidth budget.

Lazy by default: no HTTP request at all while nobody subscribes to ``image_raw/compressed``, ``camera_info``
or (with ``codec`` = ``h264``) the H.264 topics.

H.264 (``codec`` = ``h264``): a camera that streams H.264 (``Properties.Image.Format``) has its own RTSP stream
passed through, not re-encoded (:mod:`~axis_ptz_ros2.streaming.rtsp_source`, port ``rtsp_port``, stamped with
the camera's capture time); for one that does not (the 214), :class:`~axis_ptz_ros2.streaming.h264.H264Stage`
turns its JPEGs (asked for at compression 0) into H.264. Either way one H.264 stream is shared by
``image_raw/ffmpeg`` (``FFMPEGPacket``) and ``image_raw/foxglove`` (``CompressedVideo``): the same bytes, one access
unit per message, stamped with the frame's capture time; read or encoded only while one of them has a subscriber.
A new subscriber, a reconnect, or a consumer's report of decode errors on ``video/feedback`` asks for an IDR (from
the camera: RTSP ``Renew-Stream``).
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from ffmpeg_image_transport_msgs.msg import FFMPEGPacket
from foxglove_msgs.msg import CompressedVideo
from rcl_interfaces.msg import SetParametersResult
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import CameraInfo, CompressedImage

from axis_ptz_interfaces.msg import LinkFeedback, PtzState
from axis_ptz_interfaces.msg import VideoParams as VideoParamsMsg
from axis_ptz_interfaces.srv import SetVideoParams
from axis_ptz_ros2.camera_info import fill_camera_info_msg
from axis_ptz_ros2.camera_models import CameraProfile, load_generic_base
from axis_ptz_ros2.config import default_config_path, load_camera_model
from axis_ptz_ros2.nodes.camera_info_service import PARAMS as CAMERA_INFO_PARAMS
from axis_ptz_ros2.nodes.camera_info_service import CameraInfoService
from axis_ptz_ros2.nodes.common import (
    CONNECTION_PARAMS,
    FEEDBACK_QOS,
    LATCHED_QOS,
    STREAM_QOS,
    VIDEO_QOS,
    ParamSpec,
    camera_config_from_params,
    camera_info_msg,
    check_params,
    declare_params,
    diagnostic,
    field_spec,
    jpeg_format,
    publisher,
    snapshot,
    stamp_from_ns,
)
from axis_ptz_ros2.nodes.runner import run_nodes
from axis_ptz_ros2.streaming import BitrateMeter, ReaderConfig, StreamReader, StreamState
from axis_ptz_ros2.streaming.controller import VideoController, VideoSettings
from axis_ptz_ros2.streaming.discovery import CameraDiscovery
from axis_ptz_ros2.streaming.feedback import FeedbackReport
from axis_ptz_ros2.streaming.h264 import (
    BITRATE_RANGE_KBPS,
    CODECS,
    FFMPEG_ENCODING,
    H264_PRESETS,
    KEYFRAME_RANGE,
    H264Stage,
    StagedFrame,
)
from axis_ptz_ros2.streaming.jpeg import jpeg_sof
from axis_ptz_ros2.streaming.rtsp_source import passthrough_source
from axis_ptz_ros2.streaming.status import LogLine, LogThrottle, diagnostic_status, reader_event_line
from axis_ptz_ros2.vapix import VapixClient
from axis_ptz_ros2.vapix.models import COMPRESSION_RANGE, FPS_RANGE


def _live(field: str, description: str, unit: str = "", **kw: Any) -> ParamSpec:
    """A live video parameter: fills ``VideoSettings.<field>``, its default from there."""
    return field_spec(VideoSettings, field, description, unit, **kw)


def _timing(name: str, description: str, low: float, high: float) -> ParamSpec:
    """A read-only timing of the reader [s]: the parameter ``name`` fills ``ReaderConfig.<name>_s``."""
    return field_spec(ReaderConfig, f"{name}_s", description, "s", name=name, float_range=(low, high), read_only=True)


PARAMS: tuple[ParamSpec, ...] = (
    # -- video (live): defaults from VideoSettings, ranges from the VAPIX models --
    _live("fps", "frames per second requested from the camera", "1/s", int_range=FPS_RANGE),
    _live(
        "resolution",
        "image size 'WIDTHxHEIGHT' (or a CIF name), from the camera's list (Properties.Image.Resolution); "
        "'' = the largest the camera lists",
        "px",
    ),
    _live(
        "compression",
        "JPEG compression (0 = best quality, 100 = smallest)",
        int_range=COMPRESSION_RANGE,
    ),
    _live(
        "max_bitrate_kbps",
        "bandwidth budget: step compression, then fps, then resolution down to stay under it (0 = off); "
        "codec h264: caps the encoder's bitrate instead",
        "kbit/s",
        int_range=(0, 1_000_000),
    ),
    _live(
        "budget_max_compression",
        "highest compression the budget may choose before lowering fps",
        int_range=COMPRESSION_RANGE,
    ),
    _live(
        "budget_min_fps",
        "the budget lowers fps only down to this before lowering the resolution (then below it)",
        "1/s",
        int_range=FPS_RANGE,
    ),
    _live(
        "adapt_to_link",
        "follow the consumers' video/feedback: a budget from what arrives at them (see README, Weak link)",
    ),
    _live(
        "link_release",
        "drop the feedback budget after this long without a report (held through shorter silences: link cuts)",
        "s",
        float_range=(2.0, 3600.0),
    ),
    _live(
        "codec",
        "'h264': image_raw/ffmpeg and image_raw/foxglove carry H.264: a camera that streams H.264 passes its own "
        "through (RTSP), others are asked for compression 0 and encoded here; the budget drives the bitrate "
        "instead of the MJPEG ladder",
        choices=CODECS,
    ),
    _live(
        "h264_bitrate_kbps",
        "H.264 bitrate; applies as is without feedback, a lower budget (link or max_bitrate_kbps) lowers it",
        "kbit/s",
        int_range=BITRATE_RANGE_KBPS,
    ),
    _live(
        "h264_keyframe_interval",
        "frames between periodic IDRs (at most fps, one second, applies)",
        "frames",
        int_range=KEYFRAME_RANGE,
    ),
    _live("h264_preset", "libx264 preset (CPU against quality)", choices=H264_PRESETS),
    ParamSpec(
        "zoom", 1.0, "zoom for camera_info until ptz/state is received", "VAPIX units", float_range=(1.0, 99999.0)
    ),
    ParamSpec(
        "lazy",
        True,
        "stream only while someone subscribes to image_raw/compressed, camera_info or (codec h264) the H.264 topics",
    ),
    # -- frames and model (read-only) --
    ParamSpec("frame_id", "axis_ptz_optical_frame", "frame_id of images and camera_info", read_only=True),
    ParamSpec(
        "camera_model",
        "",
        "camera-model YAML ('' = chosen by the camera's reported model, else config/generic.yaml with the "
        "camera's own optics)",
        read_only=True,
    ),
    *CAMERA_INFO_PARAMS,  # camera_info_url, camera_name (read-only)
    # -- connection (read-only) --
    *CONNECTION_PARAMS,
    ParamSpec(
        "rtsp_port",
        554,
        "camera RTSP port (codec h264 from a camera that streams H.264)",
        int_range=(1, 65535),
        read_only=True,
    ),
    _timing("read_timeout", "socket read timeout of the stream", 0.05, 60.0),
    # -- self-healing (read-only) --
    _timing(
        "stall_timeout", "reconnect when the newest frame is older than this (at least 3 frame periods)", 0.05, 60.0
    ),
    _timing("backoff_initial", "first reconnect delay", 0.001, 60.0),
    _timing("backoff_max", "reconnect delay cap, counted from the start of the failed attempt", 0.001, 600.0),
    _timing("auth_retry", "retry delay after a refused login (401/403)", 0.01, 3600.0),
)
_SPECS = {s.name: s for s in PARAMS}


def _camera_model_path(value: str) -> str | None:
    if not value:
        return None
    p = Path(value).expanduser()
    if p.exists():
        return str(p)
    packaged = default_config_path(p.name)  # e.g. "config/axis214.yaml" from another working directory
    return str(packaged) if packaged.exists() else str(p)


class StreamNode(Node):
    """``axis_stream``: MJPEG → ``image_raw/compressed`` + ``camera_info``, live video parameters, diagnostics."""

    def __init__(self, name: str = "axis_stream", **kwargs: Any) -> None:
        """``kwargs`` go to :class:`rclpy.node.Node` (``context=``, ``parameter_overrides=``, ``namespace=``)."""
        super().__init__(name, **kwargs)
        p = declare_params(self, PARAMS)
        self._frame_id = str(p["frame_id"])
        model_file = _camera_model_path(str(p["camera_model"])) or ""
        # Until the camera has said what it is: the named file, else the generic model (replaced on discovery).
        self._model = load_camera_model(model_file) if model_file else load_generic_base()
        self._log_throttle = LogThrottle()
        reader_config = snapshot(ReaderConfig, PARAMS, p)
        meter = BitrateMeter(reader_config.meter_window_s)
        self._video = VideoController(  # raises ValueError (start-up error) if the request is invalid
            snapshot(VideoSettings, PARAMS, p), meter, camera=int(p["camera"]), on_change=self._publish_params
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

        # zoom for K: ptz/state when a PTZ node runs, else the parameter
        self._zoom_param = float(p["zoom"])
        self._zoom_ptz: float | None = None
        self._info_cache: dict[tuple[int, int, float], CameraInfo] = {}
        res = lambda: self._video.current.resolution  # noqa: E731
        self._calibration = CameraInfoService(  # camera_info_url + set_camera_info, as camera_info_manager
            self, str(p["camera_info_url"]), str(p["camera_name"]), lambda: (res().width, res().height),
            lambda: self._zoom_ptz if self._zoom_ptz is not None else self._zoom_param, self._info_cache.clear,
        )  # fmt: skip

        # publishers (the hot path reuses one message of each kind: only the reader thread publishes them)
        events = PublisherEventCallbacks(matched=lambda _info: self._update_activity())
        self._image_pub = publisher(self, CompressedImage, "image_raw/compressed", STREAM_QOS, event_callbacks=events)
        self._info_pub = publisher(self, CameraInfo, "camera_info", STREAM_QOS, event_callbacks=events)
        self._params_pub = publisher(self, VideoParamsMsg, "video/params", LATCHED_QOS)
        self._diag_pub = publisher(self, DiagnosticArray, "/diagnostics", 10)
        self._image_msg = CompressedImage()
        self._image_msg.header.frame_id = self._frame_id
        self._ffmpeg_pub = publisher(self, FFMPEGPacket, "image_raw/ffmpeg", VIDEO_QOS, event_callbacks=events)
        self._foxglove_pub = publisher(self, CompressedVideo, "image_raw/foxglove", VIDEO_QOS, event_callbacks=events)
        self._ffmpeg_msg = FFMPEGPacket(encoding=FFMPEG_ENCODING, is_bigendian=False)
        self._ffmpeg_msg.header.frame_id = self._frame_id
        self._foxglove_msg = CompressedVideo(format="h264", frame_id=self._frame_id)
        self._h264_subscribers = 0
        self._ffmpeg_wanted = self._foxglove_wanted = False
        self._stage = H264Stage(
            self._video.h264_settings,
            self._publish_h264,
            on_problem=lambda text: self._log(LogLine("warn", text, "h264", 10.0)),
        )
        self._told_mode = False
        self._transcode = False  # codec h264 from a camera that cannot stream it: the MJPEG feeds the stage
        self._rtsp = passthrough_source(  # codec h264 from a camera that streams it: its own H.264, as it is
            self._client,
            int(p["rtsp_port"]),
            lambda: self._video.current,
            self._video.h264_settings,
            self._stage,
            reader_config,
            on_supported=lambda _ok: self._update_activity(),
            on_event=lambda text: self._log(LogLine("warn", text, "rtsp", 10.0)),
        )

        self.create_subscription(PtzState, "ptz/state", self._on_ptz_state, STREAM_QOS)
        self.create_subscription(LinkFeedback, "video/feedback", self._on_feedback, FEEDBACK_QOS)
        self.create_service(SetVideoParams, "video/set_params", self._on_set_video_params)
        self._lazy = bool(p["lazy"])
        self._image_wanted = False
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
        self.add_on_set_parameters_callback(self._validate_params)
        self.add_post_set_parameters_callback(self._apply_params)
        self._publish_params()
        self._reader.start()
        self._rtsp.start()
        self._discovery.start()  # learn the camera even while nobody subscribes: video/params lists its sizes
        # Activity follows publisher-matched events at once; this 1 Hz timer is only the fallback poll,
        # the byte-trickle watchdog (a silent socket is caught by the read timeout) and diagnostics.
        self._timer = self.create_timer(1.0, self._housekeeping)

    # -- parameters ------------------------------------------------------------------------------------------
    def _settings_with(self, params: list[Parameter]) -> VideoSettings:
        values = {s.name: self.get_parameter(s.name).value for s in PARAMS if s.config is VideoSettings}
        values.update({prm.name: prm.value for prm in params if prm.name in values})
        return snapshot(VideoSettings, PARAMS, values)

    def _validate_params(self, params: list[Parameter]) -> SetParametersResult:
        """on-set: check what rclpy's descriptors cannot (resolution against the camera's list)."""
        result = check_params(_SPECS, params)
        if not result.successful:
            return result
        reason = self._video.check(self._settings_with(params), {prm.name for prm in params})
        return SetParametersResult(successful=reason is None, reason=reason or "")

    def _apply_params(self, params: list[Parameter]) -> None:
        """post-set: hand the new settings to the controller (the reader follows), take the node's own."""
        names = {prm.name for prm in params}
        if "lazy" in names:
            self._lazy = bool(self.get_parameter("lazy").value)
            self._update_activity()
        if "zoom" in names:
            self._zoom_param = float(self.get_parameter("zoom").value)
        self._video.apply(self._settings_with([]), names, self._pending_source)
        if "codec" in names:
            self._update_activity()

    def _on_set_video_params(
        self, request: SetVideoParams.Request, response: SetVideoParams.Response
    ) -> SetVideoParams.Response:
        """Set several video parameters at once: all or nothing (the parameter callbacks validate)."""
        changes: list[Parameter] = []
        if request.fps != 0:
            changes.append(Parameter("fps", Parameter.Type.INTEGER, int(request.fps)))
        if request.resolution:
            changes.append(Parameter("resolution", Parameter.Type.STRING, str(request.resolution)))
        if request.compression != -1:
            changes.append(Parameter("compression", Parameter.Type.INTEGER, int(request.compression)))
        if changes:
            self._pending_source = "service"
            try:
                result = self.set_parameters_atomically(changes)
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
        return msg

    def _publish_params(self) -> None:
        """The controller's announcement (any thread): the reader follows, ``video/params`` tells."""
        reader = getattr(self, "_reader", None)
        if reader is not None:
            reader.refresh()
        self._params_pub.publish(self._params_msg())

    # -- camera and frames (reader and discovery threads) ----------------------------------------------------
    def _on_profile(self, profile: CameraProfile, first: bool) -> None:
        self._model = profile.model
        self._info_cache.clear()
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
                size = (res.width, res.height)
            else:
                size = (sof[0], sof[1])
            zoom = self._zoom_ptz if self._zoom_ptz is not None else self._zoom_param
            key = (size[0], size[1], zoom)
            info = self._info_cache.get(key)
            if info is None:
                if len(self._info_cache) > 64:
                    self._info_cache.clear()
                model = self._calibration.apply(self._model)  # a stored calibration (set_camera_info) first
                calib = model.camera_info_at(zoom, size[0], size[1])  # measured K, D, P if configured
                info = fill_camera_info_msg(camera_info_msg(calib.intrinsics(), self._frame_id, stamp), calib)
                self._info_cache[key] = info
            info.header.stamp = stamp
            self._info_pub.publish(info)
        if self._transcode:  # (pass-through: the RTSP source feeds the stage)
            self._stage.on_jpeg(jpeg, arrival_ns)
        step = self._video.on_frame(time.monotonic())
        if step is not None:
            self.get_logger().debug(str(step))

    def _publish_h264(self, frame: StagedFrame) -> None:
        """One access unit (reader thread): the same bytes on both H.264 topics."""
        stamp = stamp_from_ns(frame.stamp_ns)
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
        self._video.on_h264_frame(time.monotonic(), len(frame.data))

    def _on_ptz_state(self, msg: PtzState) -> None:
        self._zoom_ptz = float(msg.zoom)

    def _on_feedback(self, msg: LinkFeedback) -> None:
        """A consumer's report: what it receives, judged by the controller against what was sent."""
        report = FeedbackReport(
            consumer=str(msg.consumer),
            frames=int(msg.frames),
            fps=float(msg.fps),
            kbps=float(msg.kbps),
            delay_p95_s=float(msg.delay_p95_s),
            delay_min_s=float(msg.delay_min_s),
            gap_s=float(msg.gap_s),
            window_s=float(msg.window_s) if msg.window_s > 0 else 1.0,
        )
        if self._stage.active:  # new losses at the consumer: a start point now, not at the next periodic IDR
            self._stage.consumer_errors(str(msg.consumer), int(msg.decode_errors))
        judgement = self._video.feedback(report, self._subscribed)
        if judgement is not None:
            self.get_logger().debug(str(judgement))

    def _subscribed(self, consumer: str) -> bool:
        """Whether the node named ``consumer`` (fully qualified) has a discovered image subscription (in h264 mode
        also on the H.264 topics)."""
        pubs = [self._image_pub, self._ffmpeg_pub, self._foxglove_pub] if self._video.h264 else [self._image_pub]
        for pub in pubs:
            for info in self.get_subscriptions_info_by_topic(pub.topic_name):
                ns = info.node_namespace.rstrip("/")
                if f"{ns}/{info.node_name}" == consumer:
                    return True
        return False

    # -- activity, watchdog, diagnostics (1 Hz) ------------------------------------------------------------------
    def _want_active(self) -> bool:
        # Cached for the hot path (no rmw call per frame); refreshed on matched events and at 1 Hz.
        self._image_wanted = self._image_pub.get_subscription_count() > 0
        self._info_wanted = self._info_pub.get_subscription_count() > 0
        ffmpeg = self._ffmpeg_pub.get_subscription_count()
        foxglove = self._foxglove_pub.get_subscription_count()
        self._ffmpeg_wanted, self._foxglove_wanted = ffmpeg > 0, foxglove > 0
        h264 = ffmpeg + foxglove
        if h264 > self._h264_subscribers:
            self._stage.request_idr()  # a new viewer needs a start point
        self._h264_subscribers = h264
        encode = self._video.h264 and h264 > 0
        supported = self._rtsp.supported  # None until asked (on the first activation)
        self._transcode = encode and supported is False
        if encode and supported is not None and not self._told_mode:
            self._told_mode = True
            self.get_logger().info(
                "codec h264: the camera streams H.264: its own stream (RTSP) is passed through, not re-encoded"
                if supported
                else "codec h264: the camera does not stream H.264: its MJPEG (compression 0) is transcoded to "
                "H.264 on this host"
            )
        self._stage.set_active(encode)
        self._rtsp.set_active(encode)
        return not self._lazy or self._image_wanted or self._info_wanted or self._transcode

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
            if self._transcode:  # (pass-through: the RTSP session starts with its own IDR)
                self._stage.discontinuity()  # (re)connected: an IDR first
        line = reader_event_line(state, message, self._video.current, self._reader.config.auth_retry_s)
        if line is not None:
            self._log(line)

    def _publish_diagnostics(self) -> None:
        stats = self._reader.stats()
        rate = self._reader.meter.rate(time.monotonic())
        extra: dict[str, object] = {**self._client.auth_counters.as_dict()}
        if self._video.h264:
            h = self._stage.stats
            extra |= {
                "h264 encoding": self._stage.active,
                "h264 bitrate target [kbit/s]": self._video.h264_settings().bitrate_kbps,
                "h264 access units": h.frames,
                "h264 IDRs": h.idrs,
                "h264 IDRs on demand": h.idr_requests,
                "h264 dropped inputs": h.bad_inputs,
                "h264 source": {None: "?", True: "camera (RTSP)", False: "transcoded"}[self._rtsp.supported],
                "rtsp access units": self._rtsp.stats.access_units,
                "rtsp reconnects": self._rtsp.stats.reconnects,
                "rtsp Renew-Stream": self._rtsp.stats.renews,
            }
        level, message, values = diagnostic_status(stats, rate, self._video.state(), extra)
        name = f"{self.get_fully_qualified_name()}: MJPEG stream"
        self._diag_pub.publish(diagnostic(self, name, level, message, values, hardware_id=self._client.config.base_url))

    def destroy_node(self) -> None:
        """Stop and join the reader thread (closing the stream from outside) and discovery, then the node."""
        discovery = getattr(self, "_discovery", None)
        if discovery is not None:
            discovery.stop(0.0)  # no new attempt from here on (joined below, once the reader has stopped)
        rtsp = getattr(self, "_rtsp", None)
        if rtsp is not None:
            rtsp.stop(1.5)
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
