"""The stream node: the camera's Motion-JPEG stream as ``image_raw/compressed`` + ``camera_info``.

A thin ROS layer over :class:`axis_ptz_ros2.streaming.StreamReader` (the one reader thread) and the VAPIX
client (reference ``vapix.md`` §5.1). Frames are published *from the reader thread*, byte-for-byte as the
camera sent them, stamped at arrival; ``camera_info`` goes with every frame (size from the JPEG's SOF header,
K from the camera model at the zoom reported on ``ptz/state`` or the ``zoom`` parameter), built once per
(size, zoom) and only restamped.

Video parameters (``fps``, ``resolution``, ``compression``, ``max_bitrate_kbps``) are live: validated in
the on-set callback (never sent to the camera when invalid), applied in the post-set callback by
reconnecting with the new request. ``video/set_params`` sets several atomically. ``video/params``
(latched) carries what is in effect after every change, including those of the bandwidth budget.

Lazy by default: no HTTP request at all while nobody subscribes to ``image_raw/compressed`` or
``camera_info``.
"""

from __future__ import annotations

import socket
import threading
import time
from pathlib import Path
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rcl_interfaces.msg import SetParametersResult
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import CameraInfo, CompressedImage

from axis_ptz_interfaces.msg import LinkFeedback, PtzState
from axis_ptz_interfaces.msg import VideoParams as VideoParamsMsg
from axis_ptz_interfaces.srv import SetVideoParams
from axis_ptz_ros2.camera_info import fill_camera_info_msg
from axis_ptz_ros2.camera_models import discover, load_generic_base
from axis_ptz_ros2.config import default_config_path, load_camera_model
from axis_ptz_ros2.nodes.common import (
    CONNECTION_PARAMS,
    FEEDBACK_QOS,
    LATCHED_QOS,
    STREAM_QOS,
    ParamSpec,
    camera_config_from_params,
    camera_info_msg,
    check_params,
    declare_params,
    diagnostic,
    run_nodes,
    stamp_from_ns,
)
from axis_ptz_ros2.streaming import (
    AXIS214_PAL_RESOLUTIONS,
    BandwidthController,
    BudgetConfig,
    FrameSource,
    ReaderConfig,
    StreamReader,
    StreamState,
    jpeg_size,
)
from axis_ptz_ros2.streaming.feedback import AdapterConfig, Decision, FeedbackReport, LinkAdapter
from axis_ptz_ros2.vapix import (
    AuthError,
    AxisPtzError,
    CameraUnreachable,
    InvalidArgument,
    Resolution,
    VapixClient,
    VideoParams,
)

PARAMS: tuple[ParamSpec, ...] = (
    # -- video (live) --
    ParamSpec("fps", 15, "frames per second requested from the camera", "1/s", int_range=(1, 30)),
    ParamSpec(
        "resolution",
        "",
        "image size 'WIDTHxHEIGHT' (or a CIF name), from the camera's list (Properties.Image.Resolution); "
        "'' = the largest the camera lists",
        "px",
    ),
    ParamSpec("compression", 30, "JPEG compression (0 = best quality, 100 = smallest)", int_range=(0, 100)),
    ParamSpec(
        "max_bitrate_kbps",
        0,
        "bandwidth budget: step compression, then fps, then resolution down to stay under it (0 = off)",
        "kbit/s",
        int_range=(0, 1_000_000),
    ),
    ParamSpec(
        "budget_max_compression",
        60,
        "highest compression the budget may choose before lowering fps",
        int_range=(0, 100),
    ),
    ParamSpec(
        "budget_min_fps",
        15,
        "the budget lowers fps only down to this before lowering the resolution (then below it)",
        "1/s",
        int_range=(1, 30),
    ),
    ParamSpec(
        "adapt_to_link",
        True,
        "follow the consumers' video/feedback: a budget from what arrives at them (see README, Weak link)",
    ),
    ParamSpec(
        "link_release",
        30.0,
        "drop the feedback budget after this long without a report (held through shorter silences: link cuts)",
        "s",
        float_range=(2.0, 3600.0),
    ),
    ParamSpec(
        "zoom", 1.0, "zoom for camera_info until ptz/state is received", "VAPIX units", float_range=(1.0, 99999.0)
    ),
    ParamSpec("lazy", True, "stream only while someone subscribes to image_raw/compressed or camera_info"),
    # -- frames and model (read-only) --
    ParamSpec("frame_id", "axis_ptz_optical_frame", "frame_id of images and camera_info", read_only=True),
    ParamSpec(
        "camera_model",
        "",
        "camera-model YAML ('' = chosen by the camera's reported model, else config/generic.yaml with the "
        "camera's own optics)",
        read_only=True,
    ),
    # -- connection (read-only) --
    *CONNECTION_PARAMS,
    ParamSpec("read_timeout", 5.0, "socket read timeout of the stream", "s", float_range=(0.05, 60.0), read_only=True),
    # -- self-healing (read-only) --
    ParamSpec(
        "stall_timeout",
        1.0,
        "reconnect when the newest frame is older than this (at least 3 frame periods)",
        "s",
        float_range=(0.05, 60.0),
        read_only=True,
    ),
    ParamSpec("backoff_initial", 0.1, "first reconnect delay", "s", float_range=(0.001, 60.0), read_only=True),
    ParamSpec(
        "backoff_max",
        1.0,
        "reconnect delay cap, counted from the start of the failed attempt",
        "s",
        float_range=(0.001, 600.0),
        read_only=True,
    ),
    ParamSpec(
        "auth_retry",
        10.0,
        "retry delay after a refused login (401/403)",
        "s",
        float_range=(0.01, 3600.0),
        read_only=True,
    ),
)
_SPECS = {s.name: s for s in PARAMS}
_FEEDBACK_SETTLE_S = 0.5  # s: a feedback report is judged only once its window starts this long after a switch
# s: ... except when a step up has streamed this long and the consumer has received nothing for as long (it swamps
# the link: waiting for a clean window would lose every frame for window + settle, 2.5 s, on each failed step up)
_SWAMPED_AFTER_STEP_UP_S = 1.0
_AUTO_PLACEHOLDER = Resolution(704, 576)  # resolution "" while the camera cannot list its sizes (retried)
_VIDEO = ("fps", "resolution", "compression", "max_bitrate_kbps", "budget_max_compression", "budget_min_fps")
# DiagnosticStatus.OK etc. are 1-byte ``bytes`` in rclpy; common.diagnostic wants the integer
_OK, _WARN, _ERROR, _STALE = (
    ord(x) for x in (DiagnosticStatus.OK, DiagnosticStatus.WARN, DiagnosticStatus.ERROR, DiagnosticStatus.STALE)
)
_STATE_LEVEL = {
    StreamState.STREAMING: _OK,
    StreamState.IDLE_LAZY: _OK,
    StreamState.CONNECTING: _OK,
    StreamState.STOPPED: _STALE,
    StreamState.RECONNECTING: _WARN,
    StreamState.AUTH_FAILED: _ERROR,
    StreamState.INVALID_PARAMS: _ERROR,
}


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
        self._lock = threading.Lock()
        self._frame_id = str(p["frame_id"])
        self._model_file = _camera_model_path(str(p["camera_model"])) or ""
        # Until the camera has said what it is: the named file, else the generic model (replaced on discovery).
        self._model = load_camera_model(self._model_file) if self._model_file else load_generic_base()
        self._profile_logged = False
        self._learn_lock = threading.Lock()
        self._learned: tuple[Resolution, ...] = ()  # the camera's resolution list once asked successfully
        self._resolutions: tuple[Resolution, ...] | None = None  # the camera's list, once read
        self._params_source = "startup"  # cause of the video parameters in effect (VideoParams.source)
        self._resolutions_pending = False
        self._unreachable = False  # the last attempt could not connect: probe with TCP first
        requested = self._requested_from(p)  # raises ValueError (start-up error) if invalid

        self._client = VapixClient(
            camera_config_from_params(p, timeout_s=max(float(p["read_timeout"]), float(p["connect_timeout"])))
        )

        # zoom for K: ptz/state when a PTZ node runs, else the parameter
        self._zoom_param = float(p["zoom"])
        self._zoom_ptz: float | None = None
        self._info_cache: dict[tuple[int, int, float], CameraInfo] = {}

        # publishers (the hot path reuses one message of each kind: only the reader thread publishes them)
        events = PublisherEventCallbacks(matched=lambda _info: self._update_activity())
        self._image_pub = self.create_publisher(
            CompressedImage, "image_raw/compressed", STREAM_QOS, event_callbacks=events
        )
        self._info_pub = self.create_publisher(CameraInfo, "camera_info", STREAM_QOS, event_callbacks=events)
        self._params_pub = self.create_publisher(VideoParamsMsg, "video/params", LATCHED_QOS)
        self._diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self._image_msg = CompressedImage()
        self._image_msg.format = "jpeg"
        self._image_msg.header.frame_id = self._frame_id

        self.create_subscription(PtzState, "ptz/state", self._on_ptz_state, STREAM_QOS)
        self.create_service(SetVideoParams, "video/set_params", self._on_set_video_params)

        self._budget = BandwidthController(
            requested,
            float(p["max_bitrate_kbps"]),
            AXIS214_PAL_RESOLUTIONS,
            BudgetConfig(max_compression=int(p["budget_max_compression"]), min_fps=int(p["budget_min_fps"])),
        )
        self._hand_budget = float(p["max_bitrate_kbps"])
        self._adapt = bool(p["adapt_to_link"])
        self._link = LinkAdapter(AdapterConfig(release_s=float(p["link_release"])))
        self.create_subscription(LinkFeedback, "video/feedback", self._on_feedback, FEEDBACK_QOS)
        self._lazy = bool(p["lazy"])
        self._image_wanted = False
        self._info_wanted = False
        self._pending_source = "parameter"
        self._log_throttle: dict[str, float] = {}

        self._reader = StreamReader(
            self._open,
            self._on_frame,
            self._budget.current,
            ReaderConfig(
                backoff_initial_s=float(p["backoff_initial"]),
                backoff_max_s=max(float(p["backoff_max"]), float(p["backoff_initial"])),
                auth_retry_s=float(p["auth_retry"]),
                stall_timeout_s=float(p["stall_timeout"]),
                read_timeout_s=float(p["read_timeout"]),
            ),
            on_event=self._on_reader_event,
            active=self._want_active(),
        )
        self.add_on_set_parameters_callback(self._validate_params)
        self.add_post_set_parameters_callback(self._apply_params)
        self._publish_params("startup")
        self._budget_check = 0.0
        self._stepped_up = False  # the budget's last switch was to better settings
        self._link_decision: Decision | None = None
        self._reader.start()
        self._stopping = threading.Event()
        self._learner = threading.Thread(target=self._learn_loop, name="axis-stream-learn", daemon=True)
        self._learner.start()
        # Activity follows publisher-matched events at once; this 1 Hz timer is only the fallback poll,
        # the byte-trickle watchdog (a silent socket is caught by the read timeout) and diagnostics.
        self._timer = self.create_timer(1.0, self._housekeeping)

    # -- parameters ------------------------------------------------------------------------------------------
    def _known_resolutions(self) -> tuple[Resolution, ...]:
        return self._resolutions if self._resolutions else AXIS214_PAL_RESOLUTIONS

    def _resolution_from(self, text: str) -> Resolution:
        """The parameter's resolution; '' = the largest the camera lists (704x576 until it is known)."""
        if text.strip():
            return Resolution.parse(text)
        if self._resolutions:
            return max(self._resolutions, key=lambda r: (r.width * r.height, r.width))
        return _AUTO_PLACEHOLDER

    def _requested_from(self, values: dict[str, Any]) -> VideoParams:
        """Validated VideoParams from parameter values; ValueError with the reason otherwise."""
        try:
            res = self._resolution_from(str(values["resolution"]))
            vp = VideoParams(res, int(values["fps"]), int(values["compression"]), camera=self._camera_index())
            vp.validate(self._resolutions or ())  # the camera's own list once known (never assumed)
        except InvalidArgument as err:
            raise ValueError(str(err)) from err
        return vp

    def _camera_index(self) -> int:
        return int(self.get_parameter("camera").value)

    def _current_values(self) -> dict[str, Any]:
        return {name: self.get_parameter(name).value for name in _VIDEO}

    def _validate_params(self, params: list[Parameter]) -> SetParametersResult:
        """on-set: check what rclpy's descriptors cannot (resolution against the camera's list)."""
        result = check_params(_SPECS, params)
        if not result.successful:
            return result
        values = self._current_values()
        touched = False
        for prm in params:
            if prm.name in _VIDEO:
                values[prm.name] = prm.value
                touched = True
        if touched:
            try:
                self._requested_from(values)
            except ValueError as err:
                return SetParametersResult(successful=False, reason=str(err))
        return SetParametersResult(successful=True)

    def _apply_params(self, params: list[Parameter]) -> None:
        """post-set: reconnect with the new request (and budget), publish what is in effect."""
        names = {prm.name for prm in params}
        if "lazy" in names:
            self._lazy = bool(self.get_parameter("lazy").value)
            self._update_activity()
        if "zoom" in names:
            self._zoom_param = float(self.get_parameter("zoom").value)
        if "adapt_to_link" in names or "link_release" in names:
            with self._lock:
                self._adapt = bool(self.get_parameter("adapt_to_link").value)
                self._link = LinkAdapter(AdapterConfig(release_s=float(self.get_parameter("link_release").value)))
                self._budget.set_budget(self._effective_budget(), time.monotonic())
        if names & set(_VIDEO):
            values = self._current_values()
            requested = self._requested_from(values)
            with self._lock:
                self._hand_budget = float(values["max_bitrate_kbps"])
                if names & {"budget_max_compression", "budget_min_fps"}:
                    self._budget = BandwidthController(
                        requested,
                        self._effective_budget(),
                        self._known_resolutions(),
                        BudgetConfig(
                            max_compression=int(values["budget_max_compression"]),
                            min_fps=int(values["budget_min_fps"]),
                        ),
                    )
                    current = self._budget.current
                else:
                    current = self._budget.configure(
                        requested=requested,
                        budget_kbps=self._effective_budget(),
                        now=time.monotonic(),
                    )
                self._stepped_up = False  # the user's change, not a step the link must prove
            self._reader.set_params(current)
            self._publish_params(self._pending_source)

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

    def _params_msg(self, source: str) -> VideoParamsMsg:
        """The parameters in effect (after the bandwidth budget), as a message."""
        vp = self._budget.current
        msg = VideoParamsMsg()
        msg.header.stamp = self.get_clock().now().to_msg()
        msg.header.frame_id = self._frame_id
        msg.fps = vp.fps
        msg.resolution = str(vp.resolution)
        msg.width, msg.height = vp.resolution.width, vp.resolution.height
        msg.compression = vp.compression
        msg.max_bitrate_kbps = int(self._budget.budget_kbps)
        msg.source = source
        known = sorted(self._known_resolutions(), key=lambda r: (r.width * r.height, r.width))
        msg.available_resolutions = list(dict.fromkeys(str(r) for r in known))
        return msg

    def _publish_params(self, source: str) -> None:
        self._params_source = source
        self._params_pub.publish(self._params_msg(source))

    # -- camera access (reader thread) -----------------------------------------------------------------------
    def _open(self, params: VideoParams, read_timeout_s: float) -> FrameSource:
        """Opener for the reader: learn the camera's resolution list once, then open the stream.

        While the camera is unreachable, a bare TCP connect decides first whether an HTTP attempt is worth
        it: building the HTTP client for each attempt costs ~10 ms of CPU, the probe ~0.1 ms.
        """
        if self._unreachable:
            cfg = self._client.config
            port = cfg.port if cfg.port is not None else (443 if cfg.use_https else 80)
            try:
                socket.create_connection((cfg.host, port), timeout=cfg.connect_timeout_s).close()
            except OSError as err:
                raise CameraUnreachable(f"camera {cfg.host}:{port} not accepting connections ({err})") from err
        self._unreachable = False
        try:
            return self._open_http(params, read_timeout_s)
        except CameraUnreachable:
            self._unreachable = True
            raise

    def _open_http(self, params: VideoParams, read_timeout_s: float) -> FrameSource:
        if self._resolutions is None:
            params = self._adopt(self._learn_camera(), params)
        return self._client.open_mjpeg(params, read_timeout_s)

    def _adopt(self, listed: tuple[Resolution, ...], params: VideoParams) -> VideoParams:
        """Take the camera's resolution list (once); with resolution '' switch to its largest size."""
        if not listed:
            return params
        with self._lock:
            if self._resolutions is not None:
                return self._reader.params
            self._resolutions = listed
            self._resolutions_pending = True  # housekeeping republishes video/params
            if not str(self.get_parameter("resolution").value).strip():  # auto: the camera's largest
                auto = VideoParams(self._resolution_from(""), params.fps, params.compression, camera=params.camera)
                if auto.resolution != params.resolution:
                    params = self._budget.configure(requested=auto, resolutions=listed, now=time.monotonic())
                    self._reader.set_params(params)  # the reader adopts it (a stream open now already has it)
        return params

    def _learn_loop(self) -> None:
        """Learn the camera at start-up even while nobody subscribes (lazy): video/params then advertises the
        camera's real sizes at once. Retries with back-off until the camera answers (or the stream did it)."""
        delay = 0.5
        while not self._stopping.is_set() and self._resolutions is None:
            try:
                self._adopt(self._learn_camera(), self._reader.params)
            except AuthError:
                return  # a refused login: the reader reports it and retries at its own pace (and learns then)
            if self._resolutions is not None or self._stopping.wait(delay):
                return
            delay = min(10.0, delay * 2.0)

    def _learn_camera(self) -> tuple[Resolution, ...]:
        """Ask the camera what it is (once): resolutions, pixel aspect, model; one summary line in the log."""
        with self._learn_lock:  # the start-up learner and the reader's first connection: one asks, one waits
            if not self._learned:
                self._learned = self._learn_camera_locked()
            return self._learned

    def _learn_camera_locked(self) -> tuple[Resolution, ...]:
        try:
            profile = discover(self._client, self._model_file)
        except AuthError:
            raise
        except AxisPtzError as err:
            if not isinstance(err, InvalidArgument):
                self._throttled_log("warn", "resolutions", f"cannot ask the camera what it is: {err}", 30.0)
            return ()
        with self._lock:
            self._model = profile.model
            self._info_cache.clear()
        if not self._profile_logged:
            self._profile_logged = True
            self.get_logger().info(profile.summary())
        return profile.optics.resolutions

    def _on_frame(self, jpeg: bytes, arrival_ns: int) -> None:
        """Hot path (reader thread): publish the camera's bytes and a restamped CameraInfo."""
        stamp = stamp_from_ns(arrival_ns)
        if self._image_wanted:
            msg = self._image_msg
            msg.header.stamp = stamp
            # The rosidl setter would copy into an array.array; the C converter reads any buffer, so hand
            # it the immutable bytes as they are (the only copy is rclpy's serialisation).
            msg._data = jpeg  # noqa: SLF001
            self._image_pub.publish(msg)
        if self._info_wanted:
            size = jpeg_size(jpeg)
            if size is None:
                res = self._reader.params.resolution
                size = (res.width, res.height)
            zoom = self._zoom_ptz if self._zoom_ptz is not None else self._zoom_param
            key = (size[0], size[1], zoom)
            info = self._info_cache.get(key)
            if info is None:
                if len(self._info_cache) > 64:
                    self._info_cache.clear()
                calib = self._model.camera_info_at(zoom, size[0], size[1])  # measured K, D, P if configured
                info = fill_camera_info_msg(camera_info_msg(calib.intrinsics(), self._frame_id, stamp), calib)
                self._info_cache[key] = info
            info.header.stamp = stamp
            self._info_pub.publish(info)
        if self._budget.budget_kbps > 0 or self._budget.level != 0:
            now = time.monotonic()
            if now - self._budget_check >= 0.25:
                self._check_budget(now)

    def _on_ptz_state(self, msg: PtzState) -> None:
        self._zoom_ptz = float(msg.zoom)

    # -- link adaptation ---------------------------------------------------------------------------------------
    def _effective_budget(self) -> float:
        """The tighter of the hand-set budget and the link's (0 = none); call with the lock held."""
        budgets = [b for b in (self._hand_budget, self._link.budget_kbps if self._adapt else 0.0) if b > 0]
        return min(budgets) if budgets else 0.0

    def _on_feedback(self, msg: LinkFeedback) -> None:
        """A consumer's report: what it receives, against what was sent over the same window."""
        if not self._adapt:
            return
        now = time.monotonic()
        sent = self._reader.meter.rate(now)
        report = self._judgeable(msg, now, sent)
        if report is None:  # not evidence about the link, but the link is alive
            with self._lock:
                self._link.heard(now)
            return
        with self._lock:
            level = self._budget.level
            step_up = self._budget.predict_kbps(level - 1, sent.bytes_per_frame) if level > 0 else 0.0
            decision = self._link.report(now, report, sent.fps, sent.kbps, step_up)
            self._link_decision = decision
            self._budget.set_budget(self._effective_budget(), now)
        self.get_logger().debug(
            f"link {decision.state}: budget {decision.budget_kbps:.0f} kbit/s; {report.consumer} received "
            f"{report.fps:.1f} fps {report.kbps:.0f} kbit/s (queue {decision.queue_delay_s * 1000:.0f} ms, "
            f"delivery {decision.delivery:.2f}); sent {sent.fps:.1f} fps {sent.kbps:.0f} kbit/s; level {level}"
        )

    def _judgeable(self, msg: LinkFeedback, now: float, sent: Any) -> FeedbackReport | None:
        """The report to judge, or None when it says nothing about the link yet."""
        if msg.frames == 0 and not self._subscribed(str(msg.consumer)):
            # "nothing received" from a consumer whose subscription has not been discovered here: the writer
            # is not sending to it yet (discovery over a lossy link can take long), which says nothing of the link
            return None
        window_s = float(msg.window_s) if msg.window_s > 0 else 1.0
        # the meter restarts with each connection: its span is how long the new settings have been streaming
        if (
            self._stepped_up
            and sent.frames >= 2
            and sent.span_s >= _SWAMPED_AFTER_STEP_UP_S
            and float(msg.gap_s) >= _SWAMPED_AFTER_STEP_UP_S
        ):
            # a step up that stopped the video: judge it now as "nothing arrives" (the window's frames are
            # mostly the old settings')
            return FeedbackReport(
                str(msg.consumer), 0, 0.0, 0.0, 0.0, float(msg.delay_min_s), float(msg.gap_s), window_s
            )
        changed = self._budget.changed_at
        if changed is not None and now - changed < window_s + _FEEDBACK_SETTLE_S:
            return None  # the report's window still holds the switch (the reconnect's gap, the old settings)
        if msg.frames == 0 and sent.span_s < 0.75 * self._reader.meter.window_s:
            return None  # nothing received, but the stream has only just (re)started: not a swamped link
        return FeedbackReport(
            consumer=str(msg.consumer),
            frames=int(msg.frames),
            fps=float(msg.fps),
            kbps=float(msg.kbps),
            delay_p95_s=float(msg.delay_p95_s),
            delay_min_s=float(msg.delay_min_s),
            gap_s=float(msg.gap_s),
            window_s=window_s,
        )

    def _subscribed(self, consumer: str) -> bool:
        """Whether the node named ``consumer`` (fully qualified) has a discovered image subscription."""
        for info in self.get_subscriptions_info_by_topic(self._image_pub.topic_name):
            ns = info.node_namespace.rstrip("/")
            if f"{ns}/{info.node_name}" == consumer:
                return True
        return False

    # -- activity, watchdog, diagnostics (1 Hz) ------------------------------------------------------------------
    def _want_active(self) -> bool:
        # Cached for the hot path (no rmw call per frame); refreshed on matched events and at 1 Hz.
        self._image_wanted = self._image_pub.get_subscription_count() > 0
        self._info_wanted = self._info_pub.get_subscription_count() > 0
        return not self._lazy or self._image_wanted or self._info_wanted

    def _update_activity(self) -> None:
        reader = getattr(self, "_reader", None)
        if reader is not None:
            reader.set_active(self._want_active())

    def _housekeeping(self) -> None:
        self._update_activity()
        self._reader.check_watchdog()
        with self._lock:
            if self._adapt:
                before = self._link.budget_kbps
                self._link.tick(time.monotonic())
                if self._link.budget_kbps != before:  # released after a long silence: back to the hand budget
                    self._budget.set_budget(self._effective_budget(), time.monotonic())
            learned = self._resolutions_pending and bool(self._resolutions)
            if learned:
                self._resolutions_pending = False
                self._budget.configure(resolutions=self._resolutions, now=time.monotonic())
        if learned:  # the camera's own list is known now: tell the teleops (latched); the values and their
            self._publish_params(self._params_source)  # cause are unchanged, so the source stays as it was
        self._publish_diagnostics()

    def _check_budget(self, now: float) -> None:
        """Reader thread, 4 Hz while a budget is set: measure, and switch parameters when it says so."""
        self._budget_check = now
        reader = self._reader
        with self._lock:
            if self._budget.budget_kbps <= 0 and self._budget.level == 0:
                return
            rate = reader.meter.rate(now)
            before = self._budget.level
            choice = self._budget.update(now, rate.kbps, rate.fps, rate.bytes_per_frame, rate.frames)
            if choice is None:
                return
            after, budget = self._budget.level, self._budget.budget_kbps
            self._stepped_up = after < before
        self.get_logger().debug(
            f"budget {budget:.0f} kbit/s: level {before} -> {after} ({choice.resolution} @ {choice.fps} "
            f"c{choice.compression}); measured {rate.kbps:.0f} kbit/s {rate.fps:.1f} fps "
            f"{rate.bytes_per_frame:.0f} B/frame over {rate.span_s:.2f} s"
        )
        reader.set_params(choice)  # closes this stream: the reader reconnects with the new request
        self._publish_params("bandwidth_budget")

    # -- events and diagnostics ------------------------------------------------------------------------------
    def _throttled_log(self, level: str, key: str, text: str, period: float) -> None:
        now = time.monotonic()
        if now - self._log_throttle.get(key, -1e9) < period:
            return
        self._log_throttle[key] = now
        logger = self.get_logger()
        # One call site per severity: rclpy refuses a second severity from the same caller line.
        if level == "info":
            logger.info(text)
        elif level == "warn":
            logger.warning(text)
        else:
            logger.error(text)

    def _on_reader_event(self, state: StreamState, message: str) -> None:
        """Reader state changes and errors (reader thread); throttled so an absent camera is not spammed."""
        if state is StreamState.AUTH_FAILED:
            self._throttled_log(
                "error",
                "auth",
                f"camera refused the login: {message} (check password_file / AXIS_USERNAME / AXIS_PASSWORD; "
                f"retrying every {self._reader.config.auth_retry_s:g} s)",
                30.0,
            )
        elif state is StreamState.INVALID_PARAMS:
            self._throttled_log("error", "invalid", f"camera cannot stream these parameters: {message}", 10.0)
        elif state is StreamState.RECONNECTING:
            self._throttled_log("warn", "reconnect", f"stream lost, reconnecting: {message}", 5.0)
        elif state is StreamState.STREAMING:
            self._log_throttle.pop("reconnect", None)
            self.get_logger().info(f"streaming {self._reader.params.resolution} @ {self._reader.params.fps} fps")

    def _publish_diagnostics(self) -> None:
        s = self._reader.stats()
        rate = self._reader.meter.rate(time.monotonic())
        vp = s.params
        values = {
            "state": s.state.value,
            "fps": rate.fps,
            "kbit/s": rate.kbps,
            "frame age [s]": s.frame_age_s if s.frame_age_s is not None else float("nan"),
            "frames": s.frames,
            "drops": s.drops,
            "truncated": s.parser.dropped_truncated,
            "corrupt": s.parser.dropped_corrupt,
            "garbage bytes": s.parser.garbage_bytes,
            "resyncs": s.parser.resyncs,
            "reconnects": s.reconnects,
            "stalls": s.stalls,
            "auth failures": s.auth_failures,
            "requested": f"{vp.resolution} @ {vp.fps} fps, compression {vp.compression}",
            "max_bitrate_kbps": int(self._budget.budget_kbps),
            "budget level": self._budget.level,
            "link budget [kbit/s]": self._link.budget_kbps if self._adapt else 0.0,
            "link state": self._link.state if self._adapt else "off",
            "link queue delay [s]": self._link_decision.queue_delay_s if self._link_decision else float("nan"),
            "last error": s.last_error,
            **self._client.auth_counters.as_dict(),
        }
        level = _STATE_LEVEL[s.state]
        message = s.state.value
        if s.state is StreamState.AUTH_FAILED:
            message = "authentication failed: " + s.last_error
        elif s.state is StreamState.RECONNECTING and s.last_error:
            message = "reconnecting: " + s.last_error
        elif s.state is StreamState.INVALID_PARAMS:
            message = "invalid parameters: " + s.last_error
        name = f"{self.get_fully_qualified_name()}: MJPEG stream"
        self._diag_pub.publish(diagnostic(self, name, level, message, values, hardware_id=self._client.config.base_url))

    def destroy_node(self) -> None:
        """Stop and join the reader thread (closing the stream from outside), then the node."""
        stopping = getattr(self, "_stopping", None)
        if stopping is not None:
            stopping.set()
        reader = getattr(self, "_reader", None)
        if reader is not None:
            reader.stop(1.5)
        learner = getattr(self, "_learner", None)
        if learner is not None:
            learner.join(2.0)
        client = getattr(self, "_client", None)
        if client is not None:
            client.close()
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """``axis_stream``: the stream node on its own."""
    return run_nodes([StreamNode], args)


if __name__ == "__main__":
    raise SystemExit(main())
