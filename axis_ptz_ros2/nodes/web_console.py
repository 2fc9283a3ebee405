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
only while an HTTP client watches it. The PTZ video also goes out as H.264 (``h264_topic``, FFMPEGPacket access
units, relayed by :mod:`axis_ptz_ros2.web.h264relay`) for pages that decode it with WebCodecs; the page falls
back to MJPEG when no H.264 is published or the browser cannot decode it, and reports what it decodes
(``/api/decoder``): its decode errors go out on ``video/feedback`` (the stream node answers with an IDR).
Service calls are asynchronous with a timeout, so neither the HTTP threads nor the executor ever block for good.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from ffmpeg_image_transport_msgs.msg import FFMPEGPacket
from geometry_msgs.msg import PointStamped
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import CompressedImage, PointCloud2
from std_srvs.srv import Trigger

from axis_ptz_interfaces.msg import PtzState, PtzVelocity, VideoParams
from axis_ptz_interfaces.srv import CenterOnPixel, LookAt, MovePtz, SetVideoParams
from axis_ptz_ros2.config import RobotConfig, load_robot
from axis_ptz_ros2.nodes.bounded_calls import BoundedCalls, ServiceError
from axis_ptz_ros2.nodes.common import (
    COMMAND_QOS,
    LATCHED_QOS,
    STREAM_QOS,
    VIDEO_QOS,
    ParamSpec,
    declare_params,
    publisher,
)
from axis_ptz_ros2.nodes.link_monitor import FeedbackPublisher
from axis_ptz_ros2.nodes.runner import run_nodes
from axis_ptz_ros2.teleop import keymap
from axis_ptz_ros2.teleop.keymap import Command as TeleopCommand
from axis_ptz_ros2.web import api
from axis_ptz_ros2.web.auth import AuthThrottle, load_token
from axis_ptz_ros2.web.h264relay import H264Slot
from axis_ptz_ros2.web.panorama import cloud_msg_in_base, look_target
from axis_ptz_ros2.web.server import CommandResult, ConsoleServer, FrameSlot, serve
from axis_ptz_ros2.web.view import ConsoleModel, keymap_json, move_text

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
        "wrong tokens a client network (all of loopback, an IPv6 /64, an IPv4 address) may present per"
        " auth_window before it gets HTTP 429",
        "count",
        True,
        (1, 1000),
    ),
    ParamSpec(
        "auth_window", 60.0, "sliding window of the wrong-token throttle", "s", True, None, (1.0, 86400.0)
    ),  # fmt: skip
    ParamSpec("ptz_topic", "image_raw/compressed", "PTZ camera JPEG topic", read_only=True),
    ParamSpec(
        "h264_topic", "image_raw/ffmpeg", "PTZ camera H.264 topic (FFMPEGPacket; '' = MJPEG only)", read_only=True
    ),  # fmt: skip
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


class WebConsole(Node):
    """The ``axis_web_console`` node: HTTP server + ROS glue (see module docstring)."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("axis_web_console", **kwargs)
        self.p = declare_params(self, PARAMS)
        self.robot: RobotConfig = load_robot(self.p["robot_config"] or None)
        self.model = ConsoleModel()
        self._cloud: PointCloud2 | None = None  # decoded only when a panorama click needs it

        # --- streams: subscribed only while watched (reconciled on the executor via a guard condition)
        self._topics = {"ptz": self.p["ptz_topic"], "panorama": self.p["panorama_topic"]}
        if self.p["overlay_topic"]:
            self._topics["overlay"] = self.p["overlay_topic"]
        self._slots = {n: FrameSlot(n, self._on_watchers) for n in self._topics}
        self._image_subs: dict[str, Any] = {}
        self._h264 = H264Slot("ptz", self._on_watchers, lambda: self._feedback.add_errors(1))
        self._h264_sub: Any = None
        self._img_group = MutuallyExclusiveCallbackGroup()
        self._reconcile_gc = self.create_guard_condition(self._reconcile, self._img_group)

        # --- always-on inputs (small messages)
        self._in_group = MutuallyExclusiveCallbackGroup()
        self.create_subscription(PtzState, "ptz/state", self.model.ptz_state, STREAM_QOS,
                                 callback_group=self._in_group)  # fmt: skip
        self.create_subscription(VideoParams, "video/params", self.model.video_params, LATCHED_QOS,
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
        self._calls = BoundedCalls(self, lambda: float(self.get_parameter("service_timeout").value), self._cli_group)
        self._vel_pub = publisher(self, PtzVelocity, "ptz/cmd/velocity", COMMAND_QOS)
        # what the relayed PTZ video looks like on arrival, for the stream's link adaptation (video/feedback)
        self._feedback = FeedbackPublisher(self, self.p["ptz_topic"], callback_group=self._in_group)
        self._commands: dict[str, Callable[[dict[str, Any]], CommandResult]] = {
            "center": self._cmd_center,
            "look_panorama": self._cmd_look_panorama,
            "key": self._cmd_key,
            "video": self._cmd_video,
            "home": lambda _body: self._answer(self._calls.call(self._home, Trigger.Request()), "going home"),
            "decoder": self._cmd_decoder,
        }
        self.server = self._serve()

    # ------------------------------------------------------------------------------------------------
    # lifecycle
    # ------------------------------------------------------------------------------------------------
    def _serve(self) -> ConsoleServer:
        log = self.get_logger()
        p = self.p
        server = serve(
            self,
            bind=str(p["bind"]),
            port=int(p["port"]),
            token=load_token(str(p["token_file"])),
            tls_files=(str(p["tls_cert_file"]), str(p["tls_key_file"]), str(p["tls_cert_dir"])),
            allow_plain_http=bool(p["allow_plain_http"]),
            tls_on_loopback=bool(p["tls_on_loopback"]),
            throttle=AuthThrottle(int(p["auth_max_failures"]), float(p["auth_window"])),
            info=log.info,
            warn=log.warning,
            error=log.error,
            debug=log.debug,
        )
        self.url = server.url
        if p["url_file"]:
            tmp = Path(p["url_file"] + ".tmp")
            tmp.write_text(self.url.rstrip("/") + "\n", encoding="utf-8")
            tmp.replace(p["url_file"])
        return server

    def destroy_node(self) -> None:
        """Stop the HTTP server (ending every stream) before the node goes."""
        server = getattr(self, "server", None)
        if server is not None:
            for s in self._slots.values():
                s.close()
            self._h264.close()
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
            elif have and not want:
                self.destroy_subscription(self._image_subs.pop(name))
        want = self._h264.watchers > 0 and bool(self.p["h264_topic"])
        if want and self._h264_sub is None:
            self._h264_sub = self.create_subscription(
                FFMPEGPacket, self.p["h264_topic"], self._on_h264, VIDEO_QOS, callback_group=self._img_group,
                event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False),
            )  # fmt: skip
        elif self._h264_sub is not None and not want:
            self.destroy_subscription(self._h264_sub)
            self._h264_sub = None
        if "ptz" in self._image_subs or self._h264_sub is not None:
            self._feedback.watch()
        else:
            self._feedback.stop()

    def _on_h264(self, msg: FFMPEGPacket) -> None:
        data = msg.data.tobytes() if hasattr(msg.data, "tobytes") else bytes(msg.data)
        stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        self._feedback.add(msg, len(data))
        self.model.ptz_frame(len(data), stamp)
        if not self._h264.publish(data, bool(msg.flags & 1), stamp):
            self.get_logger().debug(f"H.264 access unit refused: {self._h264.last_refusal}")

    def _frame_callback(self, name: str) -> Callable[[CompressedImage], None]:
        slot = self._slots[name]

        def cb(msg: CompressedImage) -> None:
            data = msg.data.tobytes() if hasattr(msg.data, "tobytes") else bytes(msg.data)
            if name == "ptz":
                self._feedback.add(msg, len(data))
                self.model.ptz_frame(len(data), msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9)
            slot.publish(data)

        return cb

    def subscribed(self, name: str) -> bool:
        """True while the image topic of stream ``name`` is subscribed (``ptz.h264``: the H.264 topic; for tests)."""
        if name == "ptz.h264":
            return self._h264_sub is not None
        return name in self._image_subs

    # ------------------------------------------------------------------------------------------------
    # inputs and the page's state
    # ------------------------------------------------------------------------------------------------
    def _on_diag(self, msg: DiagnosticArray) -> None:
        for st in msg.status:
            self.model.diagnostics(st.name, st.message, {kv.key: kv.value for kv in st.values})

    def _on_cloud(self, msg: PointCloud2) -> None:
        self._cloud = msg  # one reference swap: atomic under the GIL

    def _error(self, message: str) -> None:
        self.get_logger().warning(message)
        self.model.error(message)

    def slot(self, name: str) -> FrameSlot | None:
        """ConsoleBackend: the frame slot of a stream."""
        return self._slots.get(name)

    def h264_slot(self, name: str) -> H264Slot | None:
        """ConsoleBackend: the H.264 relay (PTZ only, and only with an ``h264_topic``)."""
        return self._h264 if name == "ptz" and self.p["h264_topic"] else None

    def state(self) -> dict[str, Any]:
        """ConsoleBackend: everything the page shows."""
        overlay = self.count_publishers(self.resolve_topic_name(self._topics["overlay"])) if "overlay" in \
            self._topics else 0  # fmt: skip
        extra = {
            "stream": {"watchers": {n: sl.watchers for n, sl in self._slots.items()}},
            "h264": {
                "available": bool(self.p["h264_topic"])
                and self.count_publishers(self.resolve_topic_name(self.p["h264_topic"])) > 0,
                "subscribed": self._h264_sub is not None,
                "watchers": self._h264.watchers,
                **self._h264.counters(),
            },
            "panorama": {
                "available": self.count_publishers(self.resolve_topic_name(self._topics["panorama"])) > 0,
                "overlay": overlay > 0,
            },
            "mouse": {k: self.get_parameter(k).value for k in ("shift_zoom_delta", "ctrl_zoom_delta", "look_zoom")},
            "services": {
                "center": self._center.service_is_ready(),
                "look_at": self._look_at.service_is_ready(),
                "move_relative": self._move_rel.service_is_ready(),
                "home": self._home.service_is_ready(),
                "video": self._set_video.service_is_ready(),
            },
            "http": self.server.counters(),
        }
        return self.model.state(self.subscribed("ptz") or self.subscribed("ptz.h264"), extra)

    def keymap(self) -> dict[str, Any]:
        """ConsoleBackend: the keyboard teleop's key map for the page (quit keys left out)."""
        return keymap_json()

    # ------------------------------------------------------------------------------------------------
    # commands
    # ------------------------------------------------------------------------------------------------
    def command(self, name: str, body: dict[str, Any]) -> CommandResult:
        """ConsoleBackend: run an operator command (bounded time; refusals go to the page's message line)."""
        try:
            result = self._commands[name](body)
        except ServiceError as err:
            result = CommandResult(False, str(err), err.status)
        if not result.ok:
            self._error(f"{name}: {result.message}")
        return result

    @staticmethod
    def _answer(res: Any, what: str) -> CommandResult:
        """Success: ``what`` (+ the node's note); refusal: the node's reason."""
        if res.success:
            return CommandResult(True, what + (f" ({res.message})" if res.message else ""))
        return CommandResult(False, f"{what}: refused: {res.message or 'no reason given'}", 409)

    def _cmd_center(self, body: dict[str, Any]) -> CommandResult:
        c = api.center_request(body)
        req = CenterOnPixel.Request()
        req.target.u, req.target.v = c.click.x, c.click.y
        req.target.image_width, req.target.image_height = c.click.width, c.click.height
        req.target.zoom_delta = c.zoom_delta
        req.wait = False
        res = self._calls.call(self._center, req)
        zd = c.zoom_delta
        return self._answer(
            res, f"centring on ({c.click.x:.0f}, {c.click.y:.0f})" + (f", zoom {zd:+.0f}" if zd else "")
        )

    def _cmd_look_panorama(self, body: dict[str, Any]) -> CommandResult:
        click = api.pixel_click(body, "x", "y", "panorama")
        cloud, why = cloud_msg_in_base(self._cloud, self.robot)
        target = look_target(click, self.robot, cloud, why, time.time())
        self.model.click(target.click)
        req = LookAt.Request()
        req.target = PointStamped()
        req.target.header.frame_id = self.robot.base_frame
        req.target.header.stamp = self.get_clock().now().to_msg()
        req.target.point.x, req.target.point.y, req.target.point.z = target.point
        req.zoom = float(self.get_parameter("look_zoom").value)
        req.wait = False
        out = self._answer(self._calls.call(self._look_at, req), target.message)
        out.extra["depth_source"] = target.depth_source
        out.extra["range_m"] = target.range_m
        return out

    def _cmd_decoder(self, body: dict[str, Any]) -> CommandResult:
        r = api.decoder_request(body)
        self.model.decoder(r.mode, r.decoded, r.errors, r.codec, r.note)
        self._feedback.add_errors(r.errors)  # the stream node answers decode errors with an IDR
        return CommandResult(True, "")

    def _cmd_key(self, body: dict[str, Any]) -> CommandResult:
        label, commands, step = self.model.key(api.key_request(body))
        if not commands:
            return CommandResult(True, f"{label}: step size x = {step}", extra={"step": step})
        messages = []
        for c in commands:
            r = self._run_teleop(c)
            if not r.ok:
                return r
            messages.append(r.message)
        return CommandResult(True, f"{label}: " + "; ".join(messages), extra={"step": step})

    def _run_teleop(self, c: TeleopCommand) -> CommandResult:
        if isinstance(c, keymap.RelativeMove):
            req = MovePtz.Request()
            req.command.pan, req.command.tilt, req.command.zoom = c.pan, c.tilt, c.zoom
            req.command.speed = math.nan
            req.wait = False
            return self._answer(self._calls.call(self._move_rel, req), move_text(c))
        if isinstance(c, keymap.GoHome):
            return self._commands["home"]({})
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
        res = self._calls.call(self._set_video, req)
        p = res.params
        if not res.success:
            return CommandResult(False, res.message or "video parameters refused", 409)
        text = f"video {p.resolution} at {p.fps} fps, compression {p.compression}"
        return CommandResult(True, text + (f" ({res.message})" if res.message else ""))

    def _cmd_video(self, body: dict[str, Any]) -> CommandResult:
        v = api.video_request(body)
        messages = []
        if v.changes_stream:
            r = self._set_video_params(v.fps, v.resolution, v.compression)
            if not r.ok:
                return r
            messages.append(r.message)
        if v.max_bitrate_kbps >= 0:
            r = self._set_budget(v.max_bitrate_kbps)
            if not r.ok:
                return r
            messages.append(r.message)
        return CommandResult(True, "; ".join(messages))

    def _stream_node_name(self) -> str:
        name = str(self.p["stream_node"])
        if name:
            return name
        pubs = self.get_publishers_info_by_topic(self.resolve_topic_name("video/params"))
        if not pubs:
            raise ServiceError(503, "no stream node publishes video/params")
        info = pubs[0]
        return f"{info.node_namespace.rstrip('/')}/{info.node_name}"

    def _set_budget(self, kbps: int) -> CommandResult:
        r = self._calls.set_parameter(self._stream_node_name(), Parameter("max_bitrate_kbps", value=int(kbps)))
        if not r.successful:
            return CommandResult(False, f"bandwidth budget refused: {r.reason or 'no reason given'}", 409)
        return CommandResult(True, f"bandwidth budget {kbps} kbit/s" if kbps else "bandwidth budget off")


def main(args: list[str] | None = None) -> int:
    """Entry point of ``axis_web_console``."""
    return run_nodes([WebConsole], args)
