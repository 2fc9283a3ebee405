"""``axis_web_console``: the operator's browser console (the thesis's mouse teleop, §3.4.5 / §5.4, on a page).

Serves a page over HTTP (stdlib server in one managed thread, :mod:`axis_ptz_ros2.web.server`) showing the
PTZ video and the panorama, and turns the operator's mouse and keys into the PTZ node's services:

* click in the PTZ image → ``ptz/center`` (that pixel to the centre); SHIFT+click also zooms +2000 units,
  CTRL+click −5000 units (``PixelTarget.zoom_delta``);
* double-click in the panorama → ray (``pointing.panorama_ray``) → depth from ``laser/points`` / ground /
  default range (``pointing.point_along_ray``) → ``ptz/look_at`` the 3-D point in base_link at zoom 1;
* the keyboard teleop's keys (``teleop/keymap.py``, one table for the terminal and the page);
* video quality: ``video/set_params`` (fps, resolution, compression) and the stream node's
  ``max_bitrate_kbps`` parameter (bandwidth budget).

Video is passed through (JPEG bytes of the CompressedImage, never re-encoded); each image topic is subscribed
only while an HTTP client watches it. Service calls are asynchronous with a timeout, so neither the HTTP
threads nor the executor ever block for good.
"""

from __future__ import annotations

import math
import os
import threading
import time
from collections import deque
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PointStamped
from rcl_interfaces.msg import Parameter as ParameterMsg
from rcl_interfaces.msg import ParameterType, ParameterValue
from rcl_interfaces.srv import SetParameters
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.client import Client
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import CompressedImage, PointCloud2
from std_srvs.srv import Trigger

from axis_ptz_interfaces.msg import PtzState, PtzVelocity, VideoParams
from axis_ptz_interfaces.srv import CenterOnPixel, LookAt, MovePtz, SetVideoParams
from axis_ptz_ros2.config import RobotConfig, load_robot
from axis_ptz_ros2.nodes.common import (
    COMMAND_QOS,
    LATCHED_QOS,
    STREAM_QOS,
    ParamSpec,
    declare_params,
    publisher,
    run_nodes,
)
from axis_ptz_ros2.nodes.link_monitor import FeedbackPublisher
from axis_ptz_ros2.pointcloud import decode_cloud_msg
from axis_ptz_ros2.pointing import panorama_ray, point_along_ray
from axis_ptz_ros2.teleop import keymap
from axis_ptz_ros2.web.auth import AuthThrottle
from axis_ptz_ros2.web.server import (
    BadRequest,
    CommandResult,
    ConsoleServer,
    FrameSlot,
    integer,
    is_loopback,
    needs_tls,
    number,
)
from axis_ptz_ros2.web.tls import TlsIdentity, load_identity

PARAMS: tuple[ParamSpec, ...] = (
    ParamSpec(
        "bind",
        "127.0.0.1",
        "bind address; any non-loopback address requires a token and serves HTTPS",
        read_only=True,
    ),
    ParamSpec("port", 8090, "HTTP(S) port (0 = pick a free one; the URL is logged)", "", True, (0, 65535)),
    ParamSpec(
        "token_file",
        "",
        "file whose first line is the access token (else env AXIS_WEB_TOKEN; none = no token)",
        read_only=True,
    ),
    ParamSpec("url_file", "", "write the console URL into this file once serving ('' = don't)", read_only=True),
    ParamSpec(
        "tls_cert_file",
        "",
        "PEM certificate (chain) for HTTPS, with tls_key_file; '' = generate a self-signed one when HTTPS is used",
        read_only=True,
    ),
    ParamSpec("tls_key_file", "", "PEM private key of tls_cert_file", read_only=True),
    ParamSpec(
        "tls_cert_dir",
        "",
        "keep a generated self-signed certificate here and reuse it (same fingerprint across restarts);"
        " '' = a new one at every start",
        read_only=True,
    ),
    ParamSpec(
        "allow_plain_http",
        False,
        "off loopback, serve plain HTTP instead of HTTPS (the token then crosses the network in clear)",
        read_only=True,
    ),
    ParamSpec("tls_on_loopback", False, "serve HTTPS on a loopback bind too", read_only=True),
    ParamSpec(
        "auth_max_failures",
        5,
        "wrong tokens a client address may present per auth_window before it gets HTTP 429",
        "count",
        True,
        (1, 1000),
    ),
    ParamSpec(
        "auth_window", 60.0, "sliding window of the wrong-token throttle", "s", True, None, (1.0, 86400.0)
    ),  # fmt: skip
    ParamSpec("ptz_topic", "image_raw/compressed", "PTZ camera JPEG topic", read_only=True),
    ParamSpec("panorama_topic", "panorama/image_raw/compressed", "panorama JPEG topic", read_only=True),
    ParamSpec(
        "overlay_topic",
        "axis_visualizer/compressed",
        "panorama with the PTZ view drawn on it ('' = none)",
        read_only=True,
    ),
    ParamSpec("laser_topic", "laser/points", "laser PointCloud2 used for panorama click depth", read_only=True),
    ParamSpec("robot_config", "", "robot frames YAML ('' = config/robot.yaml)", read_only=True),
    ParamSpec("service_timeout", 5.0, "longest wait for a PTZ/stream service answer", "s", False, None, (0.1, 60.0)),
    ParamSpec(
        "look_zoom", 1.0, "zoom after a panorama double-click (thesis: 1)", "VAPIX units", False, None, (1.0, 9999.0)
    ),  # fmt: skip
    ParamSpec(
        "shift_zoom_delta", 2000.0, "zoom change of SHIFT+click", "VAPIX units", False, None, (-9999.0, 9999.0)
    ),  # fmt: skip
    ParamSpec(
        "ctrl_zoom_delta", -5000.0, "zoom change of CTRL+click", "VAPIX units", False, None, (-9999.0, 9999.0)
    ),  # fmt: skip
    ParamSpec(
        "stream_node",
        "",
        "fully qualified name of the stream node (for max_bitrate_kbps); '' = the publisher of video/params",
        read_only=True,
    ),
)

#: Browser ``KeyboardEvent.key`` for the key map's special keys (letters and digits are themselves).
BROWSER_KEYS = {"<left>": "ArrowLeft", "<right>": "ArrowRight", "<up>": "ArrowUp", "<down>": "ArrowDown",
                keymap.ESC: "Escape", " ": " "}  # fmt: skip
_FROM_BROWSER = {v: k for k, v in BROWSER_KEYS.items()}
MAX_ERRORS = 8


class RateMeter:
    """Frames per second and kbit/s over a sliding window of arrivals (thread-safe)."""

    def __init__(self, window_s: float = 2.0) -> None:
        self._window = window_s
        self._events: deque[tuple[float, int]] = deque()
        self._lock = threading.Lock()

    def add(self, nbytes: int, t: float | None = None) -> None:
        """Count one frame of ``nbytes`` bytes arriving at monotonic time ``t`` (default now)."""
        t = time.monotonic() if t is None else t
        with self._lock:
            self._events.append((t, nbytes))
            self._trim(t)

    def _trim(self, now: float) -> None:
        while self._events and now - self._events[0][0] > self._window:
            self._events.popleft()

    def rates(self) -> tuple[float, float]:
        """(fps, kbit/s) over the window ending now (0, 0 with fewer than two frames)."""
        now = time.monotonic()
        with self._lock:
            self._trim(now)
            if len(self._events) < 2:
                return 0.0, 0.0
            span = max(now - self._events[0][0], 1e-3)
            n = len(self._events) - 1
            nbytes = sum(b for _, b in list(self._events)[1:])
        return n / span, nbytes * 8.0 / 1000.0 / span


class ServiceError(Exception):
    """A service call that did not give an answer: (HTTP status, reason)."""

    def __init__(self, status: int, message: str) -> None:
        super().__init__(message)
        self.status = status


class WebConsole(Node):
    """The ``axis_web_console`` node: HTTP server + ROS glue (see module docstring)."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("axis_web_console", **kwargs)
        self.p = declare_params(self, PARAMS)
        self.robot: RobotConfig = load_robot(self.p["robot_config"] or None)
        self._lock = threading.Lock()
        self._errors: deque[dict[str, Any]] = deque(maxlen=MAX_ERRORS)
        self._ptz_state: PtzState | None = None
        self._ptz_state_t = 0.0
        self._video: VideoParams | None = None
        self._diag: dict[str, str] = {}
        self._diag_t = 0.0
        self._cloud: PointCloud2 | None = None
        self._last_click: dict[str, Any] | None = None
        self._latency = deque[float](maxlen=30)
        self._meters = {"ptz": RateMeter(), "panorama": RateMeter(), "overlay": RateMeter()}
        self._teleop = keymap.TeleopState()
        self._resolutions: tuple[str, ...] = keymap.DEFAULT_RESOLUTIONS

        # --- streams: subscribed only while watched (reconciled on the executor via a guard condition)
        self._topics = {"ptz": self.p["ptz_topic"], "panorama": self.p["panorama_topic"]}
        if self.p["overlay_topic"]:
            self._topics["overlay"] = self.p["overlay_topic"]
        self._slots = {n: FrameSlot(n, self._on_watchers) for n in self._topics}
        self._image_subs: dict[str, Any] = {}
        self._img_group = MutuallyExclusiveCallbackGroup()
        self._reconcile_gc = self.create_guard_condition(self._reconcile, self._img_group)

        # --- always-on inputs (small messages)
        self._in_group = MutuallyExclusiveCallbackGroup()
        self.create_subscription(PtzState, "ptz/state", self._on_ptz_state, STREAM_QOS,
                                 callback_group=self._in_group)  # fmt: skip
        self.create_subscription(VideoParams, "video/params", self._on_video, LATCHED_QOS,
                                 callback_group=self._in_group)  # fmt: skip
        self.create_subscription(DiagnosticArray, "/diagnostics", self._on_diag, 10, callback_group=self._in_group)
        self.create_subscription(PointCloud2, self.p["laser_topic"], self._on_cloud, qos_profile_sensor_data,
                                 callback_group=self._in_group)  # fmt: skip

        # --- outputs
        self._cli_group = ReentrantCallbackGroup()
        self._center = self.create_client(CenterOnPixel, "ptz/center", callback_group=self._cli_group)
        self._look_at = self.create_client(LookAt, "ptz/look_at", callback_group=self._cli_group)
        self._move_rel = self.create_client(MovePtz, "ptz/move_relative", callback_group=self._cli_group)
        self._home = self.create_client(Trigger, "ptz/home", callback_group=self._cli_group)
        self._set_video = self.create_client(SetVideoParams, "video/set_params", callback_group=self._cli_group)
        self._param_clients: dict[str, Client] = {}
        self._vel_pub = publisher(self, PtzVelocity, "ptz/cmd/velocity", COMMAND_QOS)
        # what the relayed PTZ video looks like on arrival, for the stream's link adaptation (video/feedback)
        self._feedback = FeedbackPublisher(self, self.p["ptz_topic"], callback_group=self._in_group)

        # --- HTTP
        token = self._load_token()
        bind = str(self.p["bind"])
        tls: TlsIdentity | None = None
        if needs_tls(bind, bool(self.p["allow_plain_http"]), bool(self.p["tls_on_loopback"])):
            tls = load_identity(self.p["tls_cert_file"], self.p["tls_key_file"], bind, self.p["tls_cert_dir"])
        elif not is_loopback(bind):
            self.get_logger().warning(
                f"allow_plain_http: serving plain HTTP on {bind}: the token crosses the network unencrypted"
            )
        self.server = ConsoleServer(
            self,
            bind=bind,
            port=int(self.p["port"]),
            token=token,
            tls=tls,
            allow_plain_http=bool(self.p["allow_plain_http"]),
            throttle=AuthThrottle(int(self.p["auth_max_failures"]), float(self.p["auth_window"])),
            log=self.get_logger().error,
        )
        self.server.start()
        self.url = self.server.url
        auth = "token required" if token else "no token (loopback only)"
        self.get_logger().info(f"web console at {self.url} ({auth})")
        if tls is not None:
            origin = "generated self-signed" if tls.generated else "given"
            where = f", {tls.cert_path}" if tls.cert_path else ""
            self.get_logger().info(f"HTTPS certificate ({origin}{where}) SHA-256 fingerprint {tls.fingerprint}")
        if self.p["url_file"]:
            tmp = Path(self.p["url_file"] + ".tmp")
            tmp.write_text(self.url.rstrip("/") + "\n", encoding="utf-8")
            tmp.replace(self.p["url_file"])

    # ------------------------------------------------------------------------------------------------
    # lifecycle
    # ------------------------------------------------------------------------------------------------
    def _load_token(self) -> str | None:
        path = self.p["token_file"]
        if path:
            lines = Path(path).expanduser().read_text(encoding="utf-8").splitlines()
            tok = lines[0].strip() if lines else ""
            if not tok:
                raise ValueError("token_file is empty")
            return tok
        return os.environ.get("AXIS_WEB_TOKEN") or None

    def destroy_node(self) -> None:
        """Stop the HTTP server (ending every stream) before the node goes."""
        server = getattr(self, "server", None)
        if server is not None:
            for s in self._slots.values():
                s.close()
            server.stop()
        super().destroy_node()

    # ------------------------------------------------------------------------------------------------
    # streams
    # ------------------------------------------------------------------------------------------------
    def _on_watchers(self, name: str, count: int) -> None:
        """HTTP thread: the first client came or the last went; let the executor (un)subscribe."""
        self._reconcile_gc.trigger()

    def _reconcile(self) -> None:
        """Executor: subscribe to exactly the image topics someone watches."""
        for name, slot in self._slots.items():
            want = slot.watchers > 0
            have = name in self._image_subs
            if want and not have:
                self._image_subs[name] = self.create_subscription(
                    CompressedImage,
                    self._topics[name],
                    self._frame_callback(name),
                    STREAM_QOS,
                    callback_group=self._img_group,
                    # no QoS-event waitables: rclpy's executor crashes (InvalidHandle) when a subscription's
                    # event handler is destroyed while another thread builds the wait set, as happens here
                    # whenever the last viewer leaves
                    event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False),
                )
                if name == "ptz":
                    self._feedback.watch()
            elif have and not want:
                self.destroy_subscription(self._image_subs.pop(name))
                if name == "ptz":
                    self._feedback.stop()

    def _frame_callback(self, name: str) -> Callable[[CompressedImage], None]:
        slot, meter = self._slots[name], self._meters[name]

        def cb(msg: CompressedImage) -> None:
            data = msg.data.tobytes() if hasattr(msg.data, "tobytes") else bytes(msg.data)
            meter.add(len(data))
            if name == "ptz":
                self._feedback.add(msg, len(data))
                stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
                if stamp > 0:
                    with self._lock:
                        self._latency.append(time.time() - stamp)
            slot.publish(data)

        return cb

    def subscribed(self, name: str) -> bool:
        """True while the image topic of stream ``name`` is subscribed (for tests)."""
        return name in self._image_subs

    # ------------------------------------------------------------------------------------------------
    # inputs
    # ------------------------------------------------------------------------------------------------
    def _on_ptz_state(self, msg: PtzState) -> None:
        with self._lock:
            self._ptz_state, self._ptz_state_t = msg, time.monotonic()

    def _on_video(self, msg: VideoParams) -> None:
        with self._lock:
            self._video = msg
            if msg.available_resolutions:  # the camera's own list, from the stream node
                self._resolutions = keymap.sort_resolutions(list(msg.available_resolutions))
            self._teleop = keymap.TeleopState(
                step=self._teleop.step,
                fps=int(msg.fps),
                resolution=str(msg.resolution),
                compression=int(msg.compression),
                resolutions=self._resolutions,
            )

    def _on_diag(self, msg: DiagnosticArray) -> None:
        for st in msg.status:
            values = {kv.key: kv.value for kv in st.values}
            if "resolutions" in values:
                res = keymap.sort_resolutions([r for r in values["resolutions"].replace(",", " ").split() if r])
                if res:
                    with self._lock:
                        self._resolutions = res
            if any(k in values for k in ("fps", "kbit/s", "kbps")) and ("stream" in st.name.lower() or
                                                                         "video" in st.name.lower()):  # fmt: skip
                with self._lock:
                    self._diag = {"name": st.name, "message": st.message, **values}
                    self._diag_t = time.monotonic()

    def _on_cloud(self, msg: PointCloud2) -> None:
        with self._lock:
            self._cloud = msg

    def _error(self, message: str) -> None:
        self.get_logger().warning(message)
        with self._lock:
            self._errors.append({"time": time.time(), "message": message})

    # ------------------------------------------------------------------------------------------------
    # state for the page
    # ------------------------------------------------------------------------------------------------
    def slot(self, name: str) -> FrameSlot | None:
        """ConsoleBackend: the frame slot of a stream."""
        return self._slots.get(name)

    def state(self) -> dict[str, Any]:
        """ConsoleBackend: everything the page shows."""
        now = time.monotonic()
        with self._lock:
            s, s_t, v, diag, diag_t = self._ptz_state, self._ptz_state_t, self._video, dict(self._diag), self._diag_t
            lat = sorted(self._latency)
            errors = list(self._errors)
            click = dict(self._last_click) if self._last_click else None
            resolutions = list(self._resolutions)
            step = self._teleop.step
        ptz: dict[str, Any] | None = None
        if s is not None:
            ptz = {
                "pan_rad": s.pan, "tilt_rad": s.tilt, "pan_deg": math.degrees(s.pan), "tilt_deg": math.degrees(s.tilt),
                "zoom": s.zoom, "magnification": s.magnification, "hfov_deg": math.degrees(s.hfov),
                "vfov_deg": math.degrees(s.vfov), "moving": bool(s.moving), "age_s": now - s_t,
                "zoom_min": s.zoom_min, "zoom_max": s.zoom_max,
                # drive-safe zoom (the PTZ node's drive_* parameters): NaN cap = off, shown as null
                "zoom_capped": bool(s.zoom_capped), "zoom_cap": s.zoom_cap, "requested_zoom": s.requested_zoom,
            }  # fmt: skip
        video: dict[str, Any] | None = None
        if v is not None:
            video = {
                "fps": v.fps, "resolution": v.resolution, "width": v.width, "height": v.height,
                "compression": v.compression, "max_bitrate_kbps": v.max_bitrate_kbps, "source": v.source,
            }  # fmt: skip
        fps, kbps = self._meters["ptz"].rates()
        stream: dict[str, Any] = {
            "measured_at": "console" if self.subscribed("ptz") else "none",
            "fps": fps,
            "kbps": kbps,
            "latency_ms": lat[len(lat) // 2] * 1000.0 if lat and self.subscribed("ptz") else None,
            "watchers": {n: sl.watchers for n, sl in self._slots.items()},
        }
        driver = {**diag, "age_s": now - diag_t} if diag else None
        pano_pubs = self.count_publishers(self._resolve(self._topics["panorama"]))
        overlay_pubs = self.count_publishers(self._resolve(self._topics["overlay"])) if "overlay" in self._topics \
            else 0  # fmt: skip
        out: dict[str, Any] = _finite(
            {
                "ptz": ptz,
                "video": video,
                "resolutions": resolutions,
                "budget_kbps": video["max_bitrate_kbps"] if video else None,
                "stream": stream,
                "driver": driver,
                "panorama": {"available": pano_pubs > 0, "overlay": overlay_pubs > 0},
                "last_click": click,
                "step": step,
                "mouse": {
                    "shift_zoom_delta": self.get_parameter("shift_zoom_delta").value,
                    "ctrl_zoom_delta": self.get_parameter("ctrl_zoom_delta").value,
                    "look_zoom": self.get_parameter("look_zoom").value,
                },
                "services": {
                    "center": self._center.service_is_ready(),
                    "look_at": self._look_at.service_is_ready(),
                    "move_relative": self._move_rel.service_is_ready(),
                    "home": self._home.service_is_ready(),
                    "video": self._set_video.service_is_ready(),
                },
                "errors": errors,
                "time": time.time(),
            }
        )
        return out

    def _resolve(self, topic: str) -> str:
        return self.resolve_topic_name(topic)

    def keymap(self) -> dict[str, Any]:
        """ConsoleBackend: the keyboard teleop's key map for the page (quit keys left out)."""
        keys = []
        for k, a in keymap.KEYMAP.items():
            if a.kind is keymap.Kind.QUIT:
                continue
            keys.append({"key": k, "browser": BROWSER_KEYS.get(k, k), "label": keymap.key_label(k),
                         "kind": str(a.kind), "description": a.description})  # fmt: skip
        return {"keys": keys}

    # ------------------------------------------------------------------------------------------------
    # commands
    # ------------------------------------------------------------------------------------------------
    def command(self, name: str, body: dict[str, Any]) -> CommandResult:
        """ConsoleBackend: run an operator command (bounded time; refusals go to the page's message line)."""
        handler = {
            "center": self._cmd_center,
            "look_panorama": self._cmd_look_panorama,
            "key": self._cmd_key,
            "video": self._cmd_video,
            "home": self._cmd_home,
        }[name]
        try:
            result = handler(body)
        except ServiceError as err:
            result = CommandResult(False, str(err), err.status)
        if not result.ok:
            self._error(f"{name}: {result.message}")
        return result

    def _call(self, client: Client, request: Any) -> Any:
        """Call a service from an HTTP thread; never waits longer than ``service_timeout``."""
        timeout = float(self.get_parameter("service_timeout").value)
        deadline = time.monotonic() + timeout
        if not client.service_is_ready() and not client.wait_for_service(timeout_sec=min(timeout, 1.0)):
            raise ServiceError(503, f"service {client.srv_name} is not available")
        done = threading.Event()
        fut = client.call_async(request)
        fut.add_done_callback(lambda _f: done.set())
        if not done.wait(max(0.0, deadline - time.monotonic())):
            client.remove_pending_request(fut)
            fut.cancel()
            raise ServiceError(504, f"service {client.srv_name} did not answer within {timeout:g} s")
        res = fut.result()
        if res is None:
            raise ServiceError(502, f"service {client.srv_name} failed: {fut.exception()}")
        return res

    @staticmethod
    def _answer(res: Any, what: str) -> CommandResult:
        """Success: ``what`` (+ the node's note); refusal: the node's reason."""
        if res.success:
            return CommandResult(True, what + (f" ({res.message})" if res.message else ""))
        return CommandResult(False, f"{what}: refused: {res.message or 'no reason given'}", 409)

    def _cmd_center(self, body: dict[str, Any]) -> CommandResult:
        req = CenterOnPixel.Request()
        w, h = integer(body, "width"), integer(body, "height")
        if w <= 0 or h <= 0:
            raise BadRequest("width and height must be positive")
        u, v = number(body, "u"), number(body, "v")
        if not (0 <= u <= w and 0 <= v <= h):
            raise BadRequest(f"pixel ({u:g}, {v:g}) outside the {w}x{h} image")
        req.target.u, req.target.v = u, v
        req.target.image_width, req.target.image_height = w, h
        req.target.zoom_delta = number(body, "zoom_delta", 0.0)
        req.wait = False
        res = self._call(self._center, req)
        zd = req.target.zoom_delta
        what = f"centring on ({u:.0f}, {v:.0f})" + (f", zoom {zd:+.0f}" if zd else "")
        return self._answer(res, what)

    def _cmd_look_panorama(self, body: dict[str, Any]) -> CommandResult:
        w, h = integer(body, "width"), integer(body, "height")
        if w <= 0 or h <= 0:
            raise BadRequest("width and height must be positive")
        x, y = number(body, "x"), number(body, "y")
        if not (0 <= x <= w and 0 <= y <= h):
            raise BadRequest(f"pixel ({x:g}, {y:g}) outside the {w}x{h} panorama")
        origin, direction = panorama_ray(x, y, w, h, self.robot.panorama.pose)
        cloud, warn = self._cloud_in_base()
        rp = point_along_ray(
            origin,
            direction,
            cloud,
            ground_z=self.robot.ground_z,
            default_range=self.robot.default_range,
            cone_deg=self.robot.depth_cone_deg,
        )
        click = {
            "x": x, "y": y, "width": w, "height": h, "depth_source": str(rp.source), "range_m": rp.range_m,
            "point": [float(c) for c in rp.point_base], "laser_points": 0 if cloud is None else int(len(cloud)),
            "time": time.time(),
        }  # fmt: skip
        with self._lock:
            self._last_click = click
        req = LookAt.Request()
        req.target = PointStamped()
        req.target.header.frame_id = self.robot.base_frame
        req.target.header.stamp = self.get_clock().now().to_msg()
        req.target.point.x, req.target.point.y, req.target.point.z = (float(c) for c in rp.point_base)
        req.zoom = float(self.get_parameter("look_zoom").value)
        req.wait = False
        res = self._call(self._look_at, req)
        pt = ", ".join(f"{c:.2f}" for c in rp.point_base)
        msg = f"looking at ({pt}) m in {self.robot.base_frame}, depth {rp.source} {rp.range_m:.1f} m"
        if warn:
            msg += f" ({warn})"
        out = self._answer(res, msg)
        out.extra["depth_source"] = str(rp.source)
        out.extra["range_m"] = rp.range_m
        return out

    def _cloud_in_base(self) -> tuple[np.ndarray[Any, np.dtype[np.float64]] | None, str]:
        with self._lock:
            msg = self._cloud
        if msg is None:
            return None, "no laser data"
        frame = msg.header.frame_id.lstrip("/")
        try:
            xyz = decode_cloud_msg(msg)[:, :3]
        except ValueError as err:
            return None, f"laser cloud unusable: {err}"
        if frame in ("", self.robot.base_frame):
            return xyz, ""
        if frame == self.robot.laser.frame:
            return self.robot.laser.pose.apply(xyz), ""
        return None, f"laser frame {frame!r} unknown (expected {self.robot.laser.frame!r})"

    def _cmd_home(self, body: dict[str, Any]) -> CommandResult:
        return self._answer(self._call(self._home, Trigger.Request()), "going home")

    def _cmd_key(self, body: dict[str, Any]) -> CommandResult:
        raw = body.get("key")
        if not isinstance(raw, str) or not raw:
            raise BadRequest("'key' must be a non-empty string")
        key = _FROM_BROWSER.get(raw, raw)
        action = keymap.KEYMAP.get(key)
        if action is None or action.kind is keymap.Kind.QUIT:
            raise BadRequest(f"key {raw!r} is not in the key map")
        with self._lock:
            commands, self._teleop = keymap.apply(key, self._teleop)
            step = self._teleop.step
        if not commands:
            return CommandResult(True, f"{keymap.key_label(key)}: step size x = {step}", extra={"step": step})
        messages = []
        for c in commands:
            r = self._run_teleop(c)
            if not r.ok:
                return r
            messages.append(r.message)
        return CommandResult(True, f"{keymap.key_label(key)}: " + "; ".join(messages), extra={"step": step})

    def _run_teleop(self, c: object) -> CommandResult:
        if isinstance(c, keymap.RelativeMove):
            req = MovePtz.Request()
            req.command.pan, req.command.tilt, req.command.zoom = c.pan, c.tilt, c.zoom
            req.command.speed = math.nan
            req.wait = False
            parts = []
            if not math.isnan(c.pan):
                parts.append(f"pan {math.degrees(c.pan):+.0f}°")
            if not math.isnan(c.tilt):
                parts.append(f"tilt {math.degrees(c.tilt):+.0f}°")
            if not math.isnan(c.zoom):
                parts.append(f"zoom {c.zoom:+.0f}")
            return self._answer(self._call(self._move_rel, req), " ".join(parts))
        if isinstance(c, keymap.GoHome):
            return self._cmd_home({})
        if isinstance(c, keymap.StopMotion):
            self._vel_pub.publish(PtzVelocity(pan_rate=0.0, tilt_rate=0.0, zoom_rate=0.0))
            return CommandResult(True, "stop")
        if isinstance(c, keymap.SetVideo):
            return self._set_video_params(c.fps, c.resolution, c.compression)
        if isinstance(c, keymap.Notice):
            return CommandResult(False, c.text, 409)
        return CommandResult(True, "help")  # ToggleHelp: the page shows its own help

    def _set_video_params(self, fps: int, resolution: str, compression: int) -> CommandResult:
        req = SetVideoParams.Request(fps=fps, resolution=resolution, compression=compression)
        res = self._call(self._set_video, req)
        p = res.params
        if not res.success:
            return CommandResult(False, res.message or "video parameters refused", 409)
        text = f"video {p.resolution} at {p.fps} fps, compression {p.compression}"
        return CommandResult(True, text + (f" ({res.message})" if res.message else ""))

    def _cmd_video(self, body: dict[str, Any]) -> CommandResult:
        fps = integer(body, "fps", 0)
        compression = integer(body, "compression", -1)
        resolution = body.get("resolution") or ""
        if not isinstance(resolution, str):
            raise BadRequest("'resolution' must be a string like '704x576'")
        budget = integer(body, "max_bitrate_kbps", -1)
        if not (fps == 0 or 1 <= fps <= 30):
            raise BadRequest("fps must be 1..30 (0 = keep)")
        if not (compression == -1 or 0 <= compression <= 100):
            raise BadRequest("compression must be 0..100 (-1 = keep)")
        if budget < -1:
            raise BadRequest("max_bitrate_kbps must be >= 0 (0 = off, -1 = keep)")
        messages = []
        if fps or resolution or compression >= 0:
            r = self._set_video_params(fps, resolution, compression)
            if not r.ok:
                return r
            messages.append(r.message)
        if budget >= 0:
            r = self._set_budget(budget)
            if not r.ok:
                return r
            messages.append(r.message)
        if not messages:
            raise BadRequest("nothing to change")
        return CommandResult(True, "; ".join(messages))

    def _stream_node_name(self) -> str:
        name = str(self.p["stream_node"])
        if name:
            return name
        pubs = self.get_publishers_info_by_topic(self._resolve("video/params"))
        if not pubs:
            raise ServiceError(503, "no stream node publishes video/params")
        info = pubs[0]
        ns = info.node_namespace.rstrip("/")
        return f"{ns}/{info.node_name}"

    def _set_budget(self, kbps: int) -> CommandResult:
        node = self._stream_node_name()
        client = self._param_clients.get(node)
        if client is None:
            client = self.create_client(SetParameters, f"{node}/set_parameters", callback_group=self._cli_group)
            self._param_clients[node] = client
        req = SetParameters.Request()
        req.parameters = [
            ParameterMsg(
                name="max_bitrate_kbps",
                value=ParameterValue(type=ParameterType.PARAMETER_INTEGER, integer_value=int(kbps)),
            )
        ]
        res = self._call(client, req)
        r = res.results[0] if res.results else None
        if r is None or not r.successful:
            return CommandResult(False, f"bandwidth budget refused: {r.reason if r else 'no answer'}", 409)
        return CommandResult(True, f"bandwidth budget {kbps} kbit/s" if kbps else "bandwidth budget off")


def _finite(obj: Any) -> Any:  # noqa: ANN401 - JSON values
    """JSON has no NaN/inf: replace them by None (recursively)."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_finite(v) for v in obj]
    return obj


def main(args: list[str] | None = None) -> int:
    """Entry point of ``axis_web_console``."""
    return run_nodes([WebConsole], args)
