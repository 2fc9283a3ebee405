"""axis_web_console over real DDS and loopback HTTP: pass-through MJPEG, lazy subscriptions, newest-frame
delivery to slow clients, the command translation (mouse, panorama depth, keys, video, budget), service
timeouts, and the token / Host / Origin checks.

The PTZ and stream services here are recording test doubles on a probe node: they check what the console
asks for. The real chain (simulator → driver → console → browser) is tested in tests/browser and test_demo.
"""

from __future__ import annotations

import http.client
import json
import math
import os
import shutil
import socket
import ssl
import subprocess
import sys
import threading
import time
import types
from typing import Any

import cv2
import numpy as np
import pytest

from axis_ptz_ros2.geometry import direction_to_equirect

pytest.importorskip("rclpy")

from rclpy.callback_groups import ReentrantCallbackGroup  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from sensor_msgs.msg import CompressedImage, PointCloud2, PointField  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402

from axis_ptz_interfaces.msg import VideoParams  # noqa: E402
from axis_ptz_interfaces.srv import CenterOnPixel, LookAt, MovePtz, SetVideoParams  # noqa: E402
from axis_ptz_ros2.config import load_robot  # noqa: E402
from axis_ptz_ros2.nodes.common import LATCHED_QOS, STREAM_QOS  # noqa: E402
from axis_ptz_ros2.nodes.web_console import WebConsole  # noqa: E402
from axis_ptz_ros2.web import auth  # noqa: E402
from axis_ptz_ros2.web.server import ConsoleServer, needs_tls  # noqa: E402
from axis_ptz_ros2.web.tls import fingerprint_sha256, generate_self_signed  # noqa: E402

pytestmark = pytest.mark.ros


# ---------------------------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------------------------
def jpeg(i: int, w: int = 320, h: int = 240, noise: bool = False) -> bytes:
    """A real JPEG whose bytes differ per index (noise makes it big: a slow client cannot buffer many)."""
    rng = np.random.default_rng(i)
    img = rng.integers(0, 255, (h, w, 3), dtype=np.uint8) if noise else np.full((h, w, 3), i % 255, np.uint8)
    cv2.putText(img, str(i), (10, h // 2), cv2.FONT_HERSHEY_SIMPLEX, 1.5, (255, 255, 255), 3)
    ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 95])
    assert ok
    return buf.tobytes()


def request(
    console: WebConsole,
    method: str,
    path: str,
    body: Any = None,
    headers: dict[str, str] | None = None,
    raw: bytes | None = None,
) -> tuple[int, dict[str, str], bytes]:
    conn = http.client.HTTPConnection("127.0.0.1", console.server.port, timeout=15)
    try:
        h = dict(headers or {})
        data = raw
        if body is not None:
            data = json.dumps(body).encode()
            h.setdefault("Content-Type", "application/json")
        conn.request(method, path, body=data, headers=h)
        r = conn.getresponse()
        return r.status, {k.lower(): v for k, v in r.getheaders()}, r.read()
    finally:
        conn.close()


def post(console: WebConsole, path: str, body: Any, **kw: Any) -> tuple[int, dict[str, Any]]:
    status, _, data = request(console, "POST", path, body, **kw)
    return status, json.loads(data)


class MjpegReader:
    """A raw MJPEG client: parts as bytes, read one at a time (the caller decides how slow it is)."""

    def __init__(self, port: int, path: str, rcvbuf: int = 0) -> None:
        self.conn = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
        if rcvbuf:  # a slow link buffers little; loopback autotuning would buffer megabytes client-side
            self.conn.sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            self.conn.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
            self.conn.sock.settimeout(10)
            self.conn.sock.connect(("127.0.0.1", port))
        self.conn.request("GET", path)
        self.resp = self.conn.getresponse()
        assert self.resp.status == 200
        assert self.resp.getheader("Content-Type", "").startswith("multipart/x-mixed-replace")

    def next(self) -> bytes:
        fp = self.resp.fp
        length = None
        while True:
            line = fp.readline()
            assert line, "stream ended"
            if line.lower().startswith(b"content-length:"):
                length = int(line.split(b":", 1)[1])
            elif line in (b"\r\n", b"\n") and length is not None:
                data = fp.read(length)
                fp.readline()
                return data

    def close(self) -> None:
        self.resp.close()
        self.conn.close()


def make_console(ros: Any, **params: Any) -> WebConsole:
    overrides = [Parameter("port", value=0), Parameter("service_timeout", value=2.0)]
    overrides += [Parameter(k, value=v) for k, v in params.items()]
    return ros.add(WebConsole(context=ros.context, parameter_overrides=overrides))


class FakePtz:
    """Recording PTZ/stream services on a probe node (answers like the real nodes)."""

    def __init__(self, ros: Any, hold: threading.Event | None = None) -> None:
        self.node = ros.probe("fake_ptz")
        self.node.declare_parameter("max_bitrate_kbps", 0)
        self.requests: dict[str, list[Any]] = {}
        self.answered: dict[str, int] = {}
        self.hold = hold  # PTZ services answer only once this is set (a camera that does not answer)
        g = ReentrantCallbackGroup()
        n = self.node
        n.create_service(CenterOnPixel, "ptz/center", self._rec("center"), callback_group=g)
        n.create_service(LookAt, "ptz/look_at", self._rec("look_at"), callback_group=g)
        n.create_service(MovePtz, "ptz/move_relative", self._rec("move_relative"), callback_group=g)
        n.create_service(Trigger, "ptz/home", self._rec("home"), callback_group=g)
        n.create_service(SetVideoParams, "video/set_params", self._video, callback_group=g)
        n.create_service(Trigger, "still/capture", self._still, callback_group=g)
        self.still_pub = n.create_publisher(CompressedImage, "still/compressed", LATCHED_QOS)
        self.params_pub = n.create_publisher(VideoParams, "video/params", LATCHED_QOS)
        self.video = VideoParams(fps=10, resolution="704x576", width=704, height=576, compression=30)
        self.params_pub.publish(self.video)

    def _rec(self, name: str) -> Any:
        def cb(req: Any, resp: Any) -> Any:
            self.requests.setdefault(name, []).append(req)
            if self.hold is not None:
                self.hold.wait(60.0)
            resp.success = True
            resp.message = ""
            self.answered[name] = self.answered.get(name, 0) + 1
            return resp

        return cb

    def _still(self, req: Any, resp: Any) -> Any:
        """As the stream node: publish the still (latched), then answer with its size."""
        self.requests.setdefault("still", []).append(req)
        data = jpeg(len(self.requests["still"]), 64, 48)
        self.still_pub.publish(CompressedImage(format="jpeg", data=data))
        resp.success, resp.message = True, f"still 64x48 px, compression 0, {len(data)} bytes"
        return resp

    def _video(self, req: Any, resp: Any) -> Any:
        self.requests.setdefault("video", []).append(req)
        if req.resolution and req.resolution not in ("176x144", "352x288", "704x288", "704x576"):
            resp.success, resp.message = False, f"resolution {req.resolution} not supported by the camera"
            return resp
        v = self.video
        v.fps = req.fps or v.fps
        v.resolution = req.resolution or v.resolution
        v.compression = req.compression if req.compression >= 0 else v.compression
        v.h264_bitrate_kbps = req.h264_bitrate_kbps or v.h264_bitrate_kbps
        v.h264_max_bitrate_kbps = req.h264_max_bitrate_kbps or v.h264_max_bitrate_kbps
        self.params_pub.publish(v)
        resp.success, resp.message, resp.params = True, "", v
        return resp


# ---------------------------------------------------------------------------------------------------------
# video
# ---------------------------------------------------------------------------------------------------------
def test_mjpeg_passthrough_and_lazy_subscription(ros: Any) -> None:
    console = make_console(ros)
    probe = ros.probe()
    pub = probe.create_publisher(CompressedImage, "image_raw/compressed", STREAM_QOS)
    time.sleep(0.3)  # a window for a (wrong) subscription with nobody watching: the thing under test is none comes
    assert not console.subscribed("ptz"), "subscribed to the image topic with nobody watching"
    assert pub.get_subscription_count() == 0

    reader = MjpegReader(console.server.port, "/video/ptz.mjpg")
    ros.wait_for(lambda: pub.get_subscription_count() == 1, 5.0)
    frames = [jpeg(i) for i in range(3)]
    got: list[bytes] = []
    stop = threading.Event()

    def publish() -> None:
        i = 0
        while not stop.is_set():
            msg = CompressedImage(format="jpeg", data=frames[i % 3])
            msg.header.stamp = probe.get_clock().now().to_msg()
            pub.publish(msg)
            i += 1
            time.sleep(0.05)  # a 20 Hz camera stream, as the console gets it

    def stream_state() -> dict[str, Any]:
        return json.loads(request(console, "GET", "/api/state")[2])["stream"]

    t = threading.Thread(target=publish, daemon=True)
    t.start()
    try:
        while len(got) < 4:
            got.append(reader.next())
        # byte-for-byte what was published (no re-encoding), and new frames keep coming
        assert all(g in frames for g in got)
        assert len(set(got)) >= 2
        # the console's meter measures the window ending now: read it while frames still arrive (20 Hz
        # published; a stalled test process may see a lower rate for a moment, so poll for it)
        stream = ros.wait_for(lambda: (s := stream_state())["fps"] > 5.0 and s, 10.0)
        assert stream["measured_at"] == "console"
        assert stream["watchers"]["ptz"] == 1
        assert stream["latency_ms"] is not None
        assert 0 <= stream["latency_ms"] < 1000
    finally:
        stop.set()
        t.join()
    reader.close()
    ros.wait_for(lambda: not console.subscribed("ptz"), 5.0)
    ros.wait_for(lambda: pub.get_subscription_count() == 0, 5.0)


def test_h264_access_units_lost_on_the_way_count_in_the_consoles_feedback(ros: Any) -> None:
    """The console relays H.264 to the browser undecoded; an access unit that never arrived (a gap in ``pts``)
    still counts in its ``video/feedback`` ``lost`` (the stream node's congestion signal), as the link monitor's."""
    from ffmpeg_image_transport_msgs.msg import FFMPEGPacket

    from axis_ptz_interfaces.msg import LinkFeedback
    from axis_ptz_ros2.nodes.common import FEEDBACK_QOS, VIDEO_QOS

    console = make_console(ros, codec="h264")  # no stream node here to announce its codec on video/params
    probe = ros.probe()
    pub = probe.create_publisher(FFMPEGPacket, "image_raw/ffmpeg", VIDEO_QOS)
    reports: list[LinkFeedback] = []
    probe.create_subscription(LinkFeedback, "video/feedback", reports.append, FEEDBACK_QOS)
    conn = http.client.HTTPConnection("127.0.0.1", console.server.port, timeout=10)
    conn.request("GET", "/video/ptz.h264")  # a watcher: the console subscribes to the H.264 topic
    resp = conn.getresponse()
    try:
        assert resp.status == 200
        ros.wait_for(lambda: pub.get_subscription_count() == 1, 5.0)

        def send(pts: int) -> None:
            msg = FFMPEGPacket(encoding="h264;yuv420p;bgr8;bgr8", width=64, height=64, pts=pts, flags=int(pts == 10))
            msg.header.stamp = probe.get_clock().now().to_msg()
            msg.data = b"\x00\x00\x00\x01\x09\xf0"  # an access unit delimiter: the console does not decode
            pub.publish(msg)

        pts = 10
        for _ in range(60):  # 3 s at 20 Hz: past the first report window
            send(pts)
            pts += 1
            time.sleep(0.05)  # a 20 Hz stream: the report windows count time, so the time itself matters
        ros.wait_for(lambda: any(r.frames > 0 for r in reports), 5.0)
        assert all(r.lost == 0 for r in reports), [r.lost for r in reports]
        pts += 2  # two access units never arrive
        for _ in range(20):
            send(pts)
            pts += 1
            time.sleep(0.05)  # a 20 Hz stream: the report windows count time, so the time itself matters
        ros.wait_for(lambda: reports[-1].lost == 2, 5.0)
    finally:
        resp.close()
        conn.close()


def test_slow_client_gets_newest_frame_not_a_queue(ros: Any) -> None:
    console = make_console(ros)
    probe = ros.probe()
    pub = probe.create_publisher(CompressedImage, "image_raw/compressed", STREAM_QOS)
    frames = [jpeg(i, 704, 576, noise=True) for i in range(40)]  # ~ 300 kB each
    assert min(len(f) for f in frames) > 150_000
    reader = MjpegReader(console.server.port, "/video/ptz.mjpg", rcvbuf=64 * 1024)
    ros.wait_for(lambda: pub.get_subscription_count() == 1, 5.0)
    pub.publish(CompressedImage(format="jpeg", data=frames[0]))
    assert reader.next() == frames[0]
    # the client stops reading while 39 frames are published, each one taken by the console before the next
    for f in frames[1:]:
        pub.publish(CompressedImage(format="jpeg", data=f))
        ros.wait_for(lambda f=f: console.slot("ptz").latest()[1] == f, 5.0)
    received = []
    while True:
        received.append(reader.next())
        if received[-1] == frames[-1]:
            break
        assert len(received) < 10, "the console queued frames for a slow client"
    # at most a frame or two were in flight in the socket; the rest were dropped, never queued
    assert len(received) <= 4, f"{len(received)} frames delivered after the pause"
    reader.close()


def test_snapshot_and_unknown_stream(ros: Any) -> None:
    console = make_console(ros, overlay_topic="")
    probe = ros.probe()
    pub = probe.create_publisher(CompressedImage, "panorama/image_raw/compressed", STREAM_QOS)
    frame = jpeg(7)

    done = threading.Event()

    def keep_publishing() -> None:  # until the test has its answers (at most 5 s)
        for _ in range(100):
            if done.is_set():
                return
            pub.publish(CompressedImage(format="jpeg", data=frame))
            time.sleep(0.05)  # a 20 Hz camera stream, as the console gets it

    t = threading.Thread(target=keep_publishing, daemon=True)
    t.start()
    status, headers, body = request(console, "GET", "/video/panorama.jpg")
    assert status == 200
    assert headers["content-type"] == "image/jpeg"
    assert body == frame
    assert request(console, "GET", "/video/overlay.mjpg")[0] == 404  # overlay disabled by parameter
    assert request(console, "GET", "/video/nothing.mjpg")[0] == 404
    done.set()
    t.join()


# ---------------------------------------------------------------------------------------------------------
# commands
# ---------------------------------------------------------------------------------------------------------
def test_click_shift_ctrl_translate_to_center_requests(ros: Any) -> None:
    fake = FakePtz(ros)
    console = make_console(ros)
    status, ans = post(console, "/api/center", {"u": 100.5, "v": 50, "width": 704, "height": 576})
    assert status == 200, ans
    assert ans["ok"], ans
    status, ans = post(console, "/api/center", {"u": 352, "v": 288, "width": 704, "height": 576, "zoom_delta": 2000})
    assert status == 200
    assert ans["ok"]
    status, ans = post(console, "/api/center", {"u": 1, "v": 2, "width": 352, "height": 288, "zoom_delta": -5000})
    assert status == 200
    reqs = fake.requests["center"]
    assert [(r.target.u, r.target.v, r.target.zoom_delta) for r in reqs] == [
        (100.5, 50.0, 0.0),
        (352.0, 288.0, 2000.0),
        (1.0, 2.0, -5000.0),
    ]
    assert (reqs[2].target.image_width, reqs[2].target.image_height) == (352, 288)
    assert not any(r.wait for r in reqs)
    # malformed requests never reach the PTZ node
    for bad in (
        {"u": 1, "v": 2},
        {"u": "x", "v": 2, "width": 10, "height": 10},
        {"u": 20, "v": 2, "width": 10, "height": 10},
    ):
        status, ans = post(console, "/api/center", bad)
        assert status == 400
        assert not ans["ok"]
        assert ans["message"]
    assert len(fake.requests["center"]) == 3


def _cloud(points_laser: np.ndarray, frame: str) -> PointCloud2:
    pts = np.asarray(points_laser, dtype=np.float32)
    msg = PointCloud2()
    msg.header.frame_id = frame
    msg.height, msg.width = 1, len(pts)
    msg.fields = [PointField(name=n, offset=4 * i, datatype=PointField.FLOAT32, count=1) for i, n in enumerate("xyz")]
    msg.point_step, msg.row_step = 12, 12 * len(pts)
    msg.is_dense = True
    msg.data = pts.tobytes()
    return msg


def test_panorama_double_click_uses_laser_depth_then_ground_then_default(ros: Any) -> None:
    fake = FakePtz(ros)
    console = make_console(ros)
    robot = load_robot()
    T_pano, T_laser = robot.panorama.pose, robot.laser.pose
    W, H = 2048, 1024
    # a wall patch 6 m ahead-left of the panorama, seen by the laser
    target_base = np.array([4.0, 4.0, 1.2])
    d_pano = T_pano.inverse().apply(target_base[None, :])[0]
    x, y = direction_to_equirect(d_pano, W, H).ravel()
    patch = target_base + np.stack(
        np.meshgrid(np.linspace(-0.1, 0.1, 5), [0.0], np.linspace(-0.1, 0.1, 5)), -1
    ).reshape(-1, 3)
    probe = ros.probe()
    cloud_pub = probe.create_publisher(PointCloud2, "laser/points", 10)
    ros.wait_for(lambda: cloud_pub.get_subscription_count() == 1, 5.0)
    cloud_pub.publish(_cloud(T_laser.inverse().apply(patch), robot.laser.frame))
    ros.wait_for(lambda: console._cloud is not None, 5.0)  # noqa: SLF001

    status, ans = post(console, "/api/look_panorama", {"x": float(x), "y": float(y), "width": W, "height": H})
    assert status == 200, ans
    assert ans["ok"], ans
    assert ans["depth_source"] == "laser"
    req = fake.requests["look_at"][-1]
    got = np.array([req.target.point.x, req.target.point.y, req.target.point.z])
    assert req.target.header.frame_id == robot.base_frame
    assert np.linalg.norm(got - target_base) < 0.15, got
    assert req.zoom == 1.0
    assert not req.wait

    # below the horizon, no laser point on the ray -> ground plane
    x2, y2 = direction_to_equirect(np.array([1.0, -1.0, -0.5]), W, H).ravel()
    status, ans = post(console, "/api/look_panorama", {"x": float(x2), "y": float(y2), "width": W, "height": H})
    assert ans["depth_source"] == "ground"
    assert abs(fake.requests["look_at"][-1].target.point.z - robot.ground_z) < 1e-6
    # above the horizon, nothing -> default range, reported
    x3, y3 = direction_to_equirect(np.array([-1.0, 0.2, 0.3]), W, H).ravel()
    status, ans = post(console, "/api/look_panorama", {"x": float(x3), "y": float(y3), "width": W, "height": H})
    assert ans["depth_source"] == "default"
    assert abs(ans["range_m"] - robot.default_range) < 1e-9
    state = json.loads(request(console, "GET", "/api/state")[2])
    assert state["last_click"]["depth_source"] == "default"


def test_keys_follow_the_keyboard_teleop_map(ros: Any) -> None:
    fake = FakePtz(ros)
    console = make_console(ros)
    ros.wait_for(lambda: console.state()["video"] is not None, 5.0)
    km = json.loads(request(console, "GET", "/api/keymap")[2])["keys"]
    by_key = {k["key"]: k for k in km}
    assert by_key["<left>"]["browser"] == "ArrowLeft"
    assert by_key["A"]["label"] == "SHIFT+A"
    assert not any(k["kind"] == "quit" for k in km)

    assert post(console, "/api/key", {"key": "a"})[0] == 200
    assert post(console, "/api/key", {"key": "3"})[1]["step"] == 3
    assert post(console, "/api/key", {"key": "D"})[0] == 200  # SHIFT+D: 5*x deg right
    assert post(console, "/api/key", {"key": "ArrowUp"})[0] == 200
    assert post(console, "/api/key", {"key": "E"})[0] == 200  # SHIFT+E: zoom in 100*x
    moves = fake.requests["move_relative"]
    assert math.degrees(moves[0].command.pan) == pytest.approx(1.0)
    assert math.degrees(moves[1].command.pan) == pytest.approx(-15.0)
    assert math.degrees(moves[2].command.tilt) == pytest.approx(3.0)
    assert moves[3].command.zoom == pytest.approx(300.0)
    assert math.isnan(moves[0].command.tilt)
    assert math.isnan(moves[0].command.zoom)

    assert post(console, "/api/key", {"key": " "})[0] == 200
    assert len(fake.requests["home"]) == 1
    status, ans = post(console, "/api/key", {"key": "r"})  # fps 10 -> 13
    assert status == 200
    assert ans["ok"]
    assert fake.requests["video"][-1].fps == 13
    ros.wait_for(lambda: console.state()["video"]["fps"] == 13, 5.0)
    status, ans = post(console, "/api/key", {"key": "t"})  # 704x576 is the top of the list
    assert status == 409
    assert "top" in ans["message"]
    assert post(console, "/api/key", {"key": "Z"})[0] == 400


def test_in_h264_mode_the_quality_keys_step_the_bitrates(ros: Any) -> None:
    """Y/H act on what the stream sends: the H.264 bitrates (start and ceiling) once video/params says H.264."""
    fake = FakePtz(ros)
    console = make_console(ros)
    ros.wait_for(lambda: console.state()["video"] is not None, 5.0)
    fake.video.codec, fake.video.h264_bitrate_kbps, fake.video.h264_max_bitrate_kbps = "h264", 1000, 1500
    fake.params_pub.publish(fake.video)
    ros.wait_for(lambda: console.state()["video"]["codec"] == "h264", 5.0)
    status, ans = post(console, "/api/key", {"key": "h"})  # compression down = a bigger picture: more bits
    assert status == 200, ans
    r = fake.requests["video"][-1]
    assert r.h264_bitrate_kbps > 1000
    assert r.h264_max_bitrate_kbps >= 1500
    assert r.compression == -1  # kept
    assert f"H.264 {r.h264_bitrate_kbps} kbit/s" in ans["message"]
    ros.wait_for(lambda: console.state()["video"]["h264_bitrate_kbps"] == r.h264_bitrate_kbps, 5.0)


def test_video_controls_and_bandwidth_budget(ros: Any) -> None:
    fake = FakePtz(ros)
    console = make_console(ros)
    ros.wait_for(lambda: console.state()["video"] is not None, 5.0)
    status, ans = post(
        console, "/api/video", {"fps": 5, "resolution": "352x288", "compression": 60, "max_bitrate_kbps": 800}
    )
    assert status == 200, ans
    assert ans["ok"], ans
    r = fake.requests["video"][-1]
    assert (r.fps, r.resolution, r.compression) == (5, "352x288", 60)
    assert fake.node.get_parameter("max_bitrate_kbps").value == 800
    ros.wait_for(lambda: console.state()["video"]["resolution"] == "352x288", 5.0)
    # a refusal by the stream node comes back as the message
    status, ans = post(console, "/api/video", {"resolution": "1920x1080"})
    assert status == 409
    assert "not supported" in ans["message"]
    assert post(console, "/api/video", {"fps": 99})[0] == 400
    state = json.loads(request(console, "GET", "/api/state")[2])
    assert any("not supported" in e["message"] for e in state["errors"])


def test_service_timeout_does_not_block_http_or_executor(ros: Any) -> None:
    hold = threading.Event()
    fake = FakePtz(ros, hold=hold)
    console = make_console(ros)
    assert all(r.successful for r in console.set_parameters([Parameter("service_timeout", value=60.0)]))
    result: dict[str, Any] = {}
    center = {"u": 1, "v": 1, "width": 10, "height": 10}

    def pending() -> None:
        result["pending"] = post(console, "/api/center", center)

    t = threading.Thread(target=pending)
    t.start()
    try:
        # the service has the request and will not answer until released: the console is waiting on it
        ros.wait_for(lambda: len(fake.requests.get("center", [])) == 1, 5.0)
        # meanwhile the console still answers and the executor still delivers messages
        assert request(console, "GET", "/api/state")[0] == 200
        fake.video.fps = 21
        fake.params_pub.publish(fake.video)
        ros.wait_for(lambda: (console.state()["video"] or {}).get("fps") == 21, 3.0)
        assert t.is_alive()  # all of that while the service call was pending
        assert "pending" not in result
        # a service that does not answer within service_timeout is reported, without waiting for its answer
        assert all(r.successful for r in console.set_parameters([Parameter("service_timeout", value=2.0)]))
        t0 = time.monotonic()
        status, ans = post(console, "/api/center", center)
        elapsed = time.monotonic() - t0
        assert status == 504
        assert "did not answer" in ans["message"]
        assert "within 2 s" in ans["message"]
        assert elapsed >= 1.8  # waited for service_timeout (the upper bound: the service has not answered)
        assert len(fake.requests["center"]) == 2
        assert fake.answered.get("center", 0) == 0
        assert t.is_alive()
    finally:
        hold.set()
        t.join(30)
    # the first call (60 s allowed) gets its answer once the service answers; the late answer to the
    # abandoned call is dropped, and the console keeps serving
    status, ans = result["pending"]
    assert status == 200, ans
    assert ans["ok"], ans
    ros.wait_for(lambda: fake.answered.get("center") == 2, 5.0)
    assert request(console, "GET", "/api/state")[0] == 200


def test_missing_services_are_reported_not_hung(ros: Any) -> None:
    console = make_console(ros)
    t0 = time.monotonic()
    status, ans = post(console, "/api/home", {})
    assert status == 503
    assert "not available" in ans["message"]
    assert time.monotonic() - t0 < 3.0


# ---------------------------------------------------------------------------------------------------------
# security
# ---------------------------------------------------------------------------------------------------------
def test_token_required_when_configured(ros: Any, tmp_path: Any) -> None:
    token_file = tmp_path / "token"
    token_file.write_text("s3cret-token\n")
    console = make_console(ros, token_file=str(token_file))
    status, _, body = request(console, "GET", "/")
    assert status == 401
    assert b"Access token" in body
    assert b"s3cret" not in body
    assert request(console, "GET", "/api/state")[0] == 401
    assert request(console, "GET", "/video/ptz.mjpg")[0] == 401
    assert request(console, "GET", "/api/state", headers={"Authorization": "Bearer wrong"})[0] == 401
    assert request(console, "GET", "/api/state", headers={"Authorization": "Bearer s3cret-token"})[0] == 200
    assert request(console, "GET", "/api/state", headers={"X-Axis-Token": "s3cret-token"})[0] == 200
    # the login form sets an HttpOnly cookie that then works for the page and the video
    status, headers, _ = request(
        console,
        "POST",
        "/login",
        raw=b"token=s3cret-token",
        headers={"Content-Type": "application/x-www-form-urlencoded"},
    )
    assert status == 303
    assert "HttpOnly" in headers["set-cookie"]
    cookie = headers["set-cookie"].split(";")[0]
    status, _, body = request(console, "GET", "/", headers={"Cookie": cookie})
    assert status == 200
    assert b"Axis PTZ console" in body
    assert request(console, "GET", "/api/state", headers={"Cookie": "axis_token=nope"})[0] == 401


def test_non_loopback_bind_needs_a_token() -> None:
    class Nothing:
        pass

    # refused before any socket is bound
    with pytest.raises(ValueError, match="token"):
        ConsoleServer(Nothing(), bind="0.0.0.0", port=0, token=None)  # type: ignore[arg-type]


def test_host_origin_and_content_type_checks(ros: Any) -> None:
    FakePtz(ros)
    console = make_console(ros)
    body = {"u": 1, "v": 1, "width": 10, "height": 10}
    assert request(console, "GET", "/api/state", headers={"Host": "attacker.example:8090"})[0] == 421
    status, ans = post(console, "/api/center", body, headers={"Origin": "http://attacker.example"})
    assert status == 403
    host = f"127.0.0.1:{console.server.port}"
    status, ans = post(console, "/api/center", body, headers={"Origin": f"http://{host}"})
    assert status == 200
    assert ans["ok"]
    status, _, _ = request(
        console, "POST", "/api/center", raw=json.dumps(body).encode(), headers={"Content-Type": "text/plain"}
    )
    assert status == 415
    # static files: no traversal
    assert request(console, "GET", "/static/../server.py")[0] == 404
    assert request(console, "GET", "/static/app.js")[0] == 200


# ---------------------------------------------------------------------------------------------------------
# off loopback: HTTPS, throttled guessing, a 4xx for every bad request (issue 11)
# ---------------------------------------------------------------------------------------------------------
TOKEN = "s3cret-token"


def _token_console(ros: Any, tmp_path: Any, **params: Any) -> WebConsole:
    token_file = tmp_path / "token"
    token_file.write_text(TOKEN + "\n")
    return make_console(ros, token_file=str(token_file), **params)


def https_request(
    port: int, ctx: ssl.SSLContext, method: str, path: str, headers: dict[str, str] | None = None, body: bytes = b""
) -> tuple[int, dict[str, str], bytes]:
    conn = http.client.HTTPSConnection("127.0.0.1", port, timeout=15, context=ctx)
    try:
        conn.request(method, path, body=body or None, headers=headers or {})
        r = conn.getresponse()
        return r.status, {k.lower(): v for k, v in r.getheaders()}, r.read()
    finally:
        conn.close()


def test_https_with_a_generated_certificate_verified_against_itself(ros: Any, tmp_path: Any) -> None:
    keep = tmp_path / "tls"
    console = _token_console(ros, tmp_path, tls_on_loopback=True, tls_cert_dir=str(keep))
    port = console.server.port
    assert console.url.startswith("https://127.0.0.1:")
    cert_pem = (keep / "console-cert.pem").read_bytes()
    assert oct((keep / "console-key.pem").stat().st_mode & 0o777) == "0o600"
    # the CA is the generated certificate itself; the host name (127.0.0.1) is checked too
    ctx = ssl.create_default_context(cadata=cert_pem.decode("ascii"))
    assert ctx.check_hostname
    with (
        socket.create_connection(("127.0.0.1", port), timeout=10) as raw,
        ctx.wrap_socket(raw, server_hostname="127.0.0.1") as tls_sock,
    ):
        der = tls_sock.getpeercert(binary_form=True)
    assert der is not None
    assert fingerprint_sha256(der) == console.server.tls.fingerprint == fingerprint_sha256(cert_pem)
    status, _, body = https_request(port, ctx, "GET", "/api/state", {"Authorization": f"Bearer {TOKEN}"})
    assert status == 200
    assert "stream" in json.loads(body)
    assert https_request(port, ctx, "GET", "/api/state")[0] == 401
    # the login cookie is Secure + HttpOnly + SameSite=Strict over HTTPS, and then works
    status, headers, _ = https_request(
        port,
        ctx,
        "POST",
        "/login",
        {"Content-Type": "application/x-www-form-urlencoded"},
        f"token={TOKEN}".encode(),
    )
    assert status == 303
    attrs = [a.strip().lower() for a in headers["set-cookie"].split(";")]
    assert {"secure", "httponly", "samesite=strict", "path=/"} <= set(attrs), attrs
    cookie = headers["set-cookie"].split(";")[0]
    assert https_request(port, ctx, "GET", "/", {"Cookie": cookie})[0] == 200
    # a client that trusts only the system's CAs refuses this certificate
    with pytest.raises(ssl.SSLCertVerificationError):
        https_request(port, ssl.create_default_context(), "GET", "/api/state")
    # a plain HTTP request to the HTTPS port gets a 400 that says what to do, not a hang
    status, _, body = request(console, "GET", "/api/state", headers={"Authorization": f"Bearer {TOKEN}"})
    assert status == 400
    assert b"https://" in body


def test_generated_certificate_is_kept_and_a_given_one_is_used(ros: Any, tmp_path: Any) -> None:
    keep = tmp_path / "tls"
    first = _token_console(ros, tmp_path, tls_on_loopback=True, tls_cert_dir=str(keep)).server.tls.fingerprint
    again = _token_console(ros, tmp_path, tls_on_loopback=True, tls_cert_dir=str(keep)).server.tls.fingerprint
    assert first == again  # reused: the operator's trust survives a restart
    fresh = _token_console(ros, tmp_path, tls_on_loopback=True).server.tls.fingerprint
    assert fresh != first  # no directory: a new certificate per start
    # the user's own certificate + key
    cert_pem, key_pem = generate_self_signed("127.0.0.1")
    (tmp_path / "c.pem").write_bytes(cert_pem)
    (tmp_path / "k.pem").write_bytes(key_pem)
    console = _token_console(
        ros, tmp_path, tls_on_loopback=True, tls_cert_file=str(tmp_path / "c.pem"), tls_key_file=str(tmp_path / "k.pem")
    )
    assert console.server.tls.fingerprint == fingerprint_sha256(cert_pem)
    assert not console.server.tls.generated
    ctx = ssl.create_default_context(cadata=cert_pem.decode("ascii"))
    status = https_request(console.server.port, ctx, "GET", "/api/state", {"X-Axis-Token": TOKEN})[0]
    assert status == 200
    # a certificate without its key (or an unreadable one) is refused with the reason, never half-served
    with pytest.raises(ValueError, match="go together"):
        _token_console(ros, tmp_path, tls_on_loopback=True, tls_cert_file=str(tmp_path / "c.pem"))
    (tmp_path / "bad.pem").write_text("not a key\n")
    with pytest.raises(ValueError, match="cannot load the TLS certificate"):
        _token_console(
            ros,
            tmp_path,
            tls_on_loopback=True,
            tls_cert_file=str(tmp_path / "c.pem"),
            tls_key_file=str(tmp_path / "bad.pem"),
        )


def test_plain_http_off_loopback_only_when_explicitly_allowed() -> None:
    class Nothing:
        pass

    assert needs_tls("0.0.0.0", allow_plain_http=False)
    assert needs_tls("192.168.0.5", allow_plain_http=False)
    assert not needs_tls("0.0.0.0", allow_plain_http=True)
    assert not needs_tls("127.0.0.1", allow_plain_http=False)
    assert needs_tls("::1", allow_plain_http=False, tls_on_loopback=True)
    # refused before any socket is bound
    with pytest.raises(ValueError, match="plain HTTP"):
        ConsoleServer(Nothing(), bind="0.0.0.0", port=0, token="t")  # type: ignore[arg-type]


#: runs inside a fresh network namespace (only its own loopback): the real executable bound to 0.0.0.0
_NETNS_CLIENT = r"""
import hashlib, http.client, json, os, re, ssl, subprocess, sys, time
port, token, tmp = int(sys.argv[1]), sys.argv[2], sys.argv[3]
subprocess.run(["ip", "link", "set", "lo", "up"], check=True)
env = dict(os.environ, AXIS_WEB_TOKEN=token)
log = open(os.path.join(tmp, "console.log"), "wb")
node = subprocess.Popen(["axis_web_console", "--ros-args", "-p", "bind:=0.0.0.0", "-p", f"port:={port}",
                         "-p", f"url_file:={tmp}/url"], env=env, stdout=log, stderr=subprocess.STDOUT)
out = {}

def wait(pred, timeout):  # this script's condition wait: pred() polled every 0.1 s; its last value
    deadline = time.monotonic() + timeout
    while not (v := pred()) and time.monotonic() < deadline:
        time.sleep(0.1)  # the polling pause of this script's condition wait (it runs in another process)
    return v

def fingerprint():
    text = open(os.path.join(tmp, "console.log"), encoding="utf-8", errors="replace").read()
    return re.search(r"SHA-256 fingerprint ([0-9A-F:]{95})", text)

try:
    wait(lambda: os.path.exists(f"{tmp}/url") or node.poll() is not None, 60)
    out["url"] = open(f"{tmp}/url").read().strip()
    m = wait(fingerprint, 10)
    out["logged_fingerprint"] = m.group(1) if m else None
    # what an operator does: fetch the certificate, compare its fingerprint with the logged one, trust it
    pem = ssl.get_server_certificate(("127.0.0.1", port))
    der = ssl.PEM_cert_to_DER_cert(pem)
    out["served_fingerprint"] = ":".join(f"{b:02X}" for b in hashlib.sha256(der).digest())
    ctx = ssl.create_default_context(cadata=pem)
    c = http.client.HTTPSConnection("127.0.0.1", port, timeout=10, context=ctx)
    c.request("GET", "/api/state", headers={"Authorization": f"Bearer {token}"})
    r = c.getresponse()
    out["https_status"] = r.status
    out["state_keys"] = sorted(json.loads(r.read()))
    c.close()
    c = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
    c.request("GET", "/api/state", headers={"Authorization": f"Bearer {token}"})
    out["plain_status"] = c.getresponse().status
    c.close()
finally:
    node.terminate()
    node.wait(20)
    log.close()
    out["log"] = open(os.path.join(tmp, "console.log"), encoding="utf-8", errors="replace").read()
print(json.dumps(out))
"""


def test_off_loopback_bind_serves_https_and_logs_the_fingerprint(tmp_path: Any) -> None:
    """The real executable bound to 0.0.0.0 inside a network namespace of our own (nothing leaves it)."""
    if shutil.which("unshare") is None or shutil.which("axis_web_console") is None or os.geteuid() != 0:
        pytest.skip("needs root, unshare and the installed axis_web_console (./scripts/bootstrap)")
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    proc = subprocess.run(
        ["unshare", "--net", sys.executable, "-c", _NETNS_CLIENT, str(port), TOKEN, str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out["url"] == f"https://127.0.0.1:{port}", out
    assert out["logged_fingerprint"] is not None, out["log"][-2000:]
    assert out["logged_fingerprint"] == out["served_fingerprint"]
    assert out["https_status"] == 200
    assert "ptz" in out["state_keys"]
    assert out["plain_status"] == 400  # plain HTTP to the HTTPS port
    assert TOKEN not in out["log"]  # the token never reaches the log


class FakeMonotonic:
    """A monotonic clock that moves only when the test advances it."""

    def __init__(self, start: float = 1000.0) -> None:
        self.now = start

    def __call__(self) -> float:
        return self.now

    def advance(self, seconds: float) -> None:
        self.now += seconds


def test_every_auth_path_is_throttled_per_client_network(ros: Any, tmp_path: Any, monkeypatch: Any) -> None:
    # the throttle reads time.monotonic() through its module: give it a clock the test moves explicitly, so
    # the 2 s window neither passes while the requests are made nor has to be waited for
    clock = FakeMonotonic()
    monkeypatch.setattr(auth, "time", types.SimpleNamespace(monotonic=clock))
    console = _token_console(ros, tmp_path, auth_max_failures=3, auth_window=2.0)
    form = {"Content-Type": "application/x-www-form-urlencoded"}
    wrong = {
        "bearer": lambda: request(console, "GET", "/api/state", headers={"Authorization": "Bearer nope"}),
        "header": lambda: request(console, "GET", "/api/state", headers={"X-Axis-Token": "nope"}),
        "cookie": lambda: request(console, "GET", "/api/state", headers={"Cookie": "axis_token=nope"}),
        "login": lambda: request(console, "POST", "/login", raw=b"token=nope", headers=form),
    }
    right = {
        "bearer": lambda: request(console, "GET", "/api/state", headers={"Authorization": f"Bearer {TOKEN}"}),
        "header": lambda: request(console, "GET", "/api/state", headers={"X-Axis-Token": TOKEN}),
        "cookie": lambda: request(console, "GET", "/api/state", headers={"Cookie": f"axis_token={TOKEN}"}),
        "login": lambda: request(console, "POST", "/login", raw=f"token={TOKEN}".encode(), headers=form),
    }
    ok_status = {"bearer": 200, "header": 200, "cookie": 200, "login": 303}
    for kind in wrong:  # each path alone exhausts the allowance ...
        first = clock.now  # the first failure is counted at this instant
        for i in range(3):
            if i:
                clock.advance(0.5)  # failures at first, first + 0.5, first + 1.0
            status, headers, _ = wrong[kind]()
            assert status == 401, kind
            if kind == "cookie":  # a wrong cookie is cleared so a stale one does not keep guessing
                assert "max-age=0" in headers["set-cookie"].lower()
        assert console.server.throttle.failures("127.0.0.1") == 3
        # ... and then every path is refused, even with the right token, until the first failure leaves the
        # window (1 s from now)
        for k in right:
            status, headers, body = right[k]()
            assert status == 429, (kind, k, status)
            assert headers["retry-after"] == "1"
        assert b"try again" in wrong[kind]()[2]
        assert console.server.throttle.failures("127.0.0.1") == 3  # a guess while locked out is not counted
        # no credential presented is not a guess: the login page is still served
        status, _, body = request(console, "GET", "/")
        assert status == 401
        assert b"Access token" in body
        # another loopback address is the same client (rotating source addresses buys no fresh guesses)
        assert (
            _raw_status(
                console.server.port,
                b"GET /api/state HTTP/1.1\r\nHost: 127.0.0.1\r\nAuthorization: Bearer " + TOKEN.encode() + b"\r\n\r\n",
                source="127.0.0.2",
            )
            == 429
        )
        # not before the first failure has left the 2 s window (the server's own clock) ...
        clock.now = first + 1.99
        for k in right:
            status, headers, _ = right[k]()
            assert status == 429, (kind, k, status)
            assert headers["retry-after"] == "1"
        # ... and then the right token works again on every path
        clock.now = first + 2.0
        for k in right:
            assert right[k]()[0] == ok_status[k], (kind, k)
        # the window slides: the two later failures still count until they leave it too
        assert console.server.throttle.failures("127.0.0.1") == 2
        clock.now = first + 2.99
        assert console.server.throttle.failures("127.0.0.1") == 1
        clock.now = first + 3.0
        assert console.server.throttle.failures("127.0.0.1") == 0
        clock.advance(10.0)


def _raw(port: int, data: bytes, source: str = "127.0.0.1", pause_after: float = 0.0) -> bytes:
    """Send raw bytes, return everything the server answers until it closes (or 15 s pass)."""
    with socket.create_connection(("127.0.0.1", port), timeout=15, source_address=(source, 0)) as s:
        s.sendall(data)
        if pause_after:  # keep our side open, as a client that stalls mid-body does
            time.sleep(pause_after)  # the stalled client: the time it stalls is the thing under test
        else:
            s.shutdown(socket.SHUT_WR)
        chunks = []
        deadline = time.monotonic() + 15
        while time.monotonic() < deadline:
            try:
                c = s.recv(65536)
            except TimeoutError:
                break
            if not c:
                break
            chunks.append(c)
            if b"\r\n\r\n" in b"".join(chunks) and pause_after:
                break
        return b"".join(chunks)


def _raw_status(port: int, data: bytes, **kw: Any) -> int:
    answer = _raw(port, data, **kw)
    assert answer.startswith(b"HTTP/1."), f"no HTTP answer to {data[:80]!r}: {answer[:200]!r}"
    return int(answer.split(b" ", 2)[1])


def test_every_malformed_request_gets_a_4xx(ros: Any, tmp_path: Any) -> None:
    FakePtz(ros)
    console = _token_console(ros, tmp_path)
    console.server.io_timeout = 1.0  # s, so the short-body case answers quickly
    port = console.server.port
    host = f"Host: 127.0.0.1:{port}\r\n".encode()
    auth = f"Authorization: Bearer {TOKEN}\r\n".encode()
    js = b"Content-Type: application/json\r\n"

    def post(path: bytes, body: bytes, extra: bytes = b"", length: bytes | None = None) -> bytes:
        cl = str(len(body)).encode() if length is None else length
        return (
            b"POST "
            + path
            + b" HTTP/1.1\r\n"
            + host
            + auth
            + js
            + extra
            + b"Content-Length: "
            + cl
            + b"\r\n\r\n"
            + body
        )

    cases: list[tuple[str, bytes, int]] = [
        ("content-length not a number", post(b"/api/center", b"{}", length=b"abc"), 400),
        ("negative content-length", post(b"/api/center", b"{}", length=b"-5"), 400),
        ("non-ASCII digits", post(b"/api/center", b"{}", length="\uff12".encode()), 400),
        ("two different lengths", post(b"/api/home", b"{}", extra=b"Content-Length: 7\r\n"), 400),
        ("content-length on login", b"POST /login HTTP/1.1\r\n" + host + b"Content-Length: 1x\r\n\r\n", 400),
        (
            "chunked body",
            b"POST /api/home HTTP/1.1\r\n"
            + host
            + auth
            + js
            + b"Transfer-Encoding: chunked\r\n\r\n2\r\n{}\r\n0\r\n\r\n",
            411,
        ),
        ("oversize body", post(b"/api/home", b"", length=b"10000000"), 413),
        ("bad JSON", post(b"/api/home", b"{"), 400),
        ("JSON not an object", post(b"/api/home", b"[1, 2]"), 400),
        ("JSON nested too deep", post(b"/api/home", b"[" * 60000), 400),
        ("huge number", post(b"/api/center", b'{"u": ' + b"9" * 5000 + b"}"), 400),
        ("not UTF-8", post(b"/api/home", b"\xff\xfe{}"), 400),
        ("bad command fields", post(b"/api/center", b'{"u": "x", "v": 1, "width": 10, "height": 10}'), 400),
        ("unknown command", post(b"/api/launch", b"{}"), 404),
        ("wrong content type", post(b"/api/home", b"{}").replace(js, b"Content-Type: text/plain\r\n"), 415),
        ("unknown method", b"BREW /api/state HTTP/1.1\r\n" + host + auth + b"\r\n", 405),
        ("PUT", b"PUT /api/state HTTP/1.1\r\n" + host + auth + b"Content-Length: 2\r\n\r\n{}", 405),
        ("DELETE", b"DELETE / HTTP/1.1\r\n" + host + b"\r\n", 405),
        ("garbage request line", b"HELLO\r\n\r\n", 400),
        ("HTTP/0.9 request", b"GET /\r\n", 400),
        ("bad HTTP version", b"GET / HTTP/9.x\r\n" + host + b"\r\n", 400),
        ("no Host", b"GET /api/state HTTP/1.1\r\n" + auth + b"\r\n", 421),
        ("two Hosts", b"GET /api/state HTTP/1.1\r\n" + host + b"Host: 127.0.0.1\r\n" + auth + b"\r\n", 421),
    ]
    bad_host = b"Host: attacker.example\r\n"
    for method, path in (
        ("GET", "/login"), ("GET", "/"), ("GET", "/index.html"), ("GET", "/static/style.css"),
        ("GET", "/static/app.js"), ("GET", "/api/state"), ("GET", "/api/keymap"), ("GET", "/video/ptz.mjpg"),
        ("GET", "/video/ptz.jpg"), ("GET", "/nowhere"), ("HEAD", "/"), ("HEAD", "/login"), ("POST", "/login"),
        ("POST", "/api/home"), ("POST", "/api/center"),
    ):  # fmt: skip
        req = f"{method} {path} HTTP/1.1\r\n".encode() + bad_host + auth
        req += js + b"Content-Length: 2\r\n\r\n{}" if method == "POST" else b"\r\n"
        cases.append((f"bad Host on {method} {path}", req, 421))
    for what, data, want in cases:
        got = _raw_status(port, data)
        assert got == want, f"{what}: HTTP {got}, expected {want}"
    # a body shorter than its Content-Length: 408 once the console stops waiting (the client keeps the line open)
    answer = _raw(port, post(b"/api/home", b"{", length=b"20"), pause_after=5.0)
    assert answer.startswith(b"HTTP/1.1 408"), answer[:100]
    # the server is still healthy after all that
    assert request(console, "GET", "/api/state", headers={"X-Axis-Token": TOKEN})[0] == 200
