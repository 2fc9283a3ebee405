"""``axis_web_console``: the operator's browser console (the thesis's mouse teleop, §3.4.5 / §5.4, on a page).

Serves a page over HTTP (stdlib server in one managed thread, :mod:`axis_ptz_ros2.web.server`) showing the
PTZ video and the panorama, and turns the operator's mouse and keys into the PTZ node's services:

* click in the PTZ image → ``ptz/center`` (that pixel to the centre); SHIFT+click also zooms +2000 units,
  CTRL+click −5000 units (``PixelTarget.zoom_delta``);
* double-click in the panorama → ray (``pointing.panorama_ray``) → depth from ``laser/points`` / ground /
  default range (``pointing.point_along_ray``) → ``ptz/look_at`` the 3-D point in base_link at zoom 1;
* the keyboard teleop's keys (``teleop/keymap.py``, one table for the terminal and the page);
* video quality: ``video/set_params`` (fps, resolution, compression) and the stream node's
  ``max_bitrate_kbps`` parameter (bandwidth budget);
* the Still button (and key P) → ``still/capture``; the still (``still/compressed``) is shown beside the live view
  (:mod:`~axis_ptz_ros2.nodes.web_still`).

Video is passed through (JPEG bytes of the CompressedImage, never re-encoded); each image topic is subscribed
only while an HTTP client watches it. The PTZ video goes out as MJPEG (``ptz_topic``) or as H.264 (``h264_topic``,
FFMPEGPacket access units, relayed by :mod:`axis_ptz_ros2.web.h264relay`) for pages that decode it with WebCodecs.
Which of the two follows the stream by default (``codec`` = ``auto``): the codec the stream node announces on
``video/params`` (:mod:`axis_ptz_ros2.codec_follow`). The page asks for that one only (``ptz_video`` in its state):
H.264 while the stream is H.264 — no MJPEG subscription pulling the transcoder's compression-0 JPEGs over the link
beside it (issue 40) — MJPEG while it is MJPEG (``/video/ptz.h264`` is then refused with the reason and the H.264
subscription dropped), nothing until ``video/params`` is heard. The page falls back to MJPEG only when it cannot
decode the H.264 (no WebCodecs, a codec the browser refuses, ``?video=mjpeg``), and reports what it decodes
(``/api/decoder``): its decode errors go out on ``video/feedback`` (the stream node answers with an IDR).
Service calls are asynchronous with a timeout, so neither the HTTP threads nor the executor ever block for good.

This module holds the parameters, the always-on inputs and the HTTP server's lifecycle; the video subscriptions
are :mod:`~axis_ptz_ros2.nodes.web_streams`, the operator's commands :mod:`~axis_ptz_ros2.nodes.web_commands`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import PointCloud2

from axis_ptz_interfaces.msg import PtzState, VideoParams
from axis_ptz_ros2.codec_follow import AUTO, CHOICES
from axis_ptz_ros2.config import RobotConfig, load_robot
from axis_ptz_ros2.nodes.codec_follow import follow_stream_codec
from axis_ptz_ros2.nodes.common import LATCHED_QOS, STREAM_QOS, ParamSpec
from axis_ptz_ros2.nodes.live_params import LiveParams, Params
from axis_ptz_ros2.nodes.runner import run_nodes
from axis_ptz_ros2.nodes.web_commands import ConsoleCommands
from axis_ptz_ros2.nodes.web_still import ConsoleStill
from axis_ptz_ros2.nodes.web_streams import ConsoleStreams
from axis_ptz_ros2.web.auth import AuthThrottle, load_token
from axis_ptz_ros2.web.backend import CommandResult
from axis_ptz_ros2.web.h264relay import H264Slot
from axis_ptz_ros2.web.relay import FrameSlot
from axis_ptz_ros2.web.server import ConsoleServer, serve
from axis_ptz_ros2.web.view import ConsoleModel, keymap_json

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
    ParamSpec(
        "codec",
        AUTO,
        "PTZ video the page is given: auto = the codec the stream node announces on video/params (switched when it "
        "changes; no PTZ video until it is heard), mjpeg = ptz_topic only, h264 = h264_topic (MJPEG only for "
        "browsers that cannot decode it)",
        choices=CHOICES,
        read_only=True,
    ),
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
        self._live = LiveParams(self, PARAMS)  # service_timeout, look_zoom, *_zoom_delta: read at each use
        self.robot: RobotConfig = load_robot(self.p["robot_config"] or None)
        self.model = ConsoleModel()
        self._cloud: PointCloud2 | None = None  # decoded only when a panorama click needs it

        # --- always-on inputs (small messages)
        self._in_group = g = MutuallyExclusiveCallbackGroup()
        self.create_subscription(PtzState, "ptz/state", self.model.ptz_state, STREAM_QOS, callback_group=g)
        self.create_subscription(VideoParams, "video/params", self.model.video_params, LATCHED_QOS, callback_group=g)
        self.create_subscription(DiagnosticArray, "/diagnostics", self._on_diag, 10, callback_group=g)
        self.create_subscription(PointCloud2, self.p["laser_topic"], self._on_cloud, qos_profile_sensor_data,
                                 callback_group=g)  # fmt: skip

        # --- streams: subscribed only while watched; outputs: the operator's commands
        topics = {"ptz": self.p["ptz_topic"], "panorama": self.p["panorama_topic"]}
        if self.p["overlay_topic"]:
            topics["overlay"] = self.p["overlay_topic"]
        self._streams = ConsoleStreams(self, topics, str(self.p["h264_topic"]), self.model, g)
        codec = str(self.p["codec"])
        if not self.p["h264_topic"]:
            if codec == "h264":
                raise ValueError("invalid start-up parameter: codec=h264 needs an h264_topic ('' = MJPEG only)")
            codec = "mjpeg"  # no H.264 topic: MJPEG whatever the stream announces
        self.codec = follow_stream_codec(self, codec, self._streams.set_codec, callback_group=g)
        self._streams.set_codec(self.codec.codec)
        self._commands = ConsoleCommands(
            self, self.model, self.robot, lambda: self._live.params, self._streams.feedback, lambda: self._cloud
        )
        # the full-quality still: the page's Still button and key P (still/capture), shown from still/compressed
        self._still = ConsoleStill(self, lambda: float(self.p["service_timeout"]), g)
        self._commands.add_command("still", self._still.take)
        self.server = self._serve()

    @property
    def p(self) -> Params:
        """The parameter snapshot in effect (what ``ros2 param get`` tells)."""
        return self._live.params

    @property
    def live_params(self) -> LiveParams:
        """The node's parameters (``.params``: the snapshot in effect)."""
        return self._live

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
            self._streams.close()
            server.stop()
        super().destroy_node()

    # ------------------------------------------------------------------------------------------------
    # inputs
    # ------------------------------------------------------------------------------------------------
    def _on_diag(self, msg: DiagnosticArray) -> None:
        for st in msg.status:
            self.model.diagnostics(st.name, st.message, {kv.key: kv.value for kv in st.values})

    def _on_cloud(self, msg: PointCloud2) -> None:
        self._cloud = msg  # one reference swap: atomic under the GIL

    # ------------------------------------------------------------------------------------------------
    # ConsoleBackend (the HTTP server's view of the node)
    # ------------------------------------------------------------------------------------------------
    def subscribed(self, name: str) -> bool:
        """True while the image topic of stream ``name`` is subscribed (``ptz.h264``: the H.264 topic; for tests)."""
        return self._streams.subscribed(name)

    def slot(self, name: str) -> FrameSlot | None:
        """ConsoleBackend: the frame slot of a stream."""
        return self._still.slot if name == "still" else self._streams.slots.get(name)

    def h264_slot(self, name: str) -> H264Slot | None:
        """ConsoleBackend: the H.264 relay (PTZ only, and only while the PTZ video is H.264)."""
        return self._streams.h264 if name == "ptz" and self._streams.codec == "h264" else None

    def h264_refusal(self, name: str) -> str:
        """Why :meth:`h264_slot` gives no relay for ``name`` (the 404's text)."""
        if name != "ptz":
            return "only the PTZ video goes out as H.264"
        if self._streams.codec == "mjpeg":
            return f"the PTZ video is MJPEG ({self.codec.describe()}): /video/ptz.mjpg"
        return self.codec.describe()

    def state(self) -> dict[str, Any]:
        """ConsoleBackend: everything the page shows."""
        extra = {
            **self._streams.state(),
            "ptz_video": {"codec": self._streams.codec, "choice": self.codec.choice, "text": self.codec.describe()},
            "mouse": {k: self.p[k] for k in ("shift_zoom_delta", "ctrl_zoom_delta", "look_zoom")},
            "services": {**self._commands.services_ready(), "still": self._still.ready()},
            "still": self._still.state(),
            "http": self.server.counters(),
        }
        return self.model.state(self.subscribed("ptz") or self.subscribed("ptz.h264"), extra)

    def keymap(self) -> dict[str, Any]:
        """ConsoleBackend: the keyboard teleop's key map for the page (quit keys left out)."""
        return keymap_json()

    def command(self, name: str, body: dict[str, Any]) -> CommandResult:
        """ConsoleBackend: run an operator command (bounded time; refusals go to the page's message line)."""
        result = self._commands.run(name, body)
        if not result.ok:
            message = f"{name}: {result.message}"
            self.get_logger().warning(message)
            self.model.error(message)
        return result


def main(args: list[str] | None = None) -> int:
    """Entry point of ``axis_web_console``."""
    return run_nodes([WebConsole], args)
