"""axis_virtual_camera over real DDS: a marker in a synthetic panorama lands at K·R⁻¹·d in the published JPEG,
camera_info is the K of the render, and the PTZ interface (the teleop's and web console's messages) drives it.
"""

from __future__ import annotations

import math
import threading
import time
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("rclpy")

import cv2  # noqa: E402
import numpy as np  # noqa: E402
from geometry_msgs.msg import TransformStamped  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from sensor_msgs.msg import CameraInfo, CompressedImage, Image, JointState  # noqa: E402

from axis_ptz_interfaces.msg import PixelTarget, PtzCommand, PtzState, PtzVelocity  # noqa: E402
from axis_ptz_interfaces.srv import CenterOnPixel, MovePtz, SetZoom  # noqa: E402
from axis_ptz_ros2 import geometry as g  # noqa: E402
from axis_ptz_ros2 import transforms  # noqa: E402
from axis_ptz_ros2.nodes.common import STREAM_QOS  # noqa: E402
from axis_ptz_ros2.nodes.virtual_camera import VirtualCameraNode  # noqa: E402
from axis_ptz_ros2.teleop.keymap import TeleopState, apply  # noqa: E402
from axis_ptz_ros2.virtual.render import ViewSpec, direction_pixel  # noqa: E402

pytestmark = pytest.mark.ros

W, H = 640, 480
PW, PH = 2048, 1024
T_PANO = (0.216, -0.044, 0.75)
MARKER_PAN, MARKER_TILT = 0.7, 0.2  # rad, marker direction in base_link (az, el)
SIGMA = math.radians(0.35)  # angular size of the marker


def robot_file(tmp_path: Path, rpy: tuple[float, float, float]) -> str:
    p = tmp_path / "robot.yaml"
    p.write_text(
        "format: axis_ptz_ros2/robot/v1\nbase_frame: base_link\n"
        f"panorama:\n  frame: panorama_link\n  xyz: {list(T_PANO)}\n  rpy: {list(rpy)}\n",
        encoding="utf-8",
    )
    return str(p)


def synthetic_panorama(R_pano_base: np.ndarray, d_base: np.ndarray) -> np.ndarray:
    """BGR panorama: grey background, a white Gaussian of angular distance around the marker direction."""
    d = R_pano_base @ d_base
    xx, yy = np.meshgrid(np.arange(PW), np.arange(PH))
    dirs = g.equirect_to_direction(xx, yy, PW, PH)
    theta = np.arccos(np.clip(dirs @ (d / np.linalg.norm(d)), -1.0, 1.0))
    grey = 20.0 + 220.0 * np.exp(-0.5 * (theta / SIGMA) ** 2)
    # a coarse texture far from the marker, so the image is not trivially uniform
    grey += 10.0 * ((xx // 64 + yy // 64) % 2) * (theta > 10 * SIGMA)
    img = np.clip(np.round(grey), 0, 255).astype(np.uint8)
    return np.repeat(img[:, :, None], 3, axis=2)


def marker_centroid(jpeg: bytes, near: tuple[float, float] | None = None, half: int = 24) -> tuple[float, float]:
    """Intensity-weighted centroid of the marker (background subtracted) around ``near`` or the brightest pixel."""
    img = cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_GRAYSCALE).astype(np.float64)
    if near is None:
        v0, u0 = np.unravel_index(np.argmax(cv2.GaussianBlur(img, (9, 9), 2.0)), img.shape)
    else:
        u0, v0 = round(near[0]), round(near[1])
    v_lo, v_hi = max(0, v0 - half), min(img.shape[0], v0 + half + 1)
    u_lo, u_hi = max(0, u0 - half), min(img.shape[1], u0 + half + 1)
    win = np.clip(img[v_lo:v_hi, u_lo:u_hi] - 20.0 - 15.0, 0.0, None)  # background 20, JPEG ringing < 15
    vv, uu = np.mgrid[v_lo:v_hi, u_lo:u_hi]
    s = win.sum()
    assert s > 0, "no marker in the window"
    return float((uu * win).sum() / s), float((vv * win).sum() / s)


class Probe:
    """Publishes the panorama, collects images/camera_info/state, calls the PTZ services."""

    def __init__(self, ros: Any, raw: bool) -> None:
        self.ros = ros
        self.node = ros.probe("vc_probe")
        self.raw = raw
        if raw:
            self.pano_pub = self.node.create_publisher(Image, "panorama/image_raw", STREAM_QOS)
        else:
            self.pano_pub = self.node.create_publisher(CompressedImage, "panorama/image_raw/compressed", STREAM_QOS)
        self.lock = threading.Lock()
        self.images: list[CompressedImage] = []
        self.infos: dict[tuple[int, int], CameraInfo] = {}
        self.state: PtzState | None = None
        self.transform: TransformStamped | None = None
        self.transforms: dict[tuple[int, int], TransformStamped] = {}  # by stamp: pair it with a joint state
        self.joints: JointState | None = None
        self.joints_by_stamp: dict[tuple[int, int], JointState] = {}
        self.node.create_subscription(TransformStamped, "ptz/transform", self._on_tf, STREAM_QOS)
        self.node.create_subscription(JointState, "joint_states", self._on_joints, STREAM_QOS)
        self.node.create_subscription(CompressedImage, "image_raw/compressed", self._on_image, STREAM_QOS)
        self.node.create_subscription(CameraInfo, "camera_info", self._on_info, STREAM_QOS)
        self.node.create_subscription(PtzState, "ptz/state", self._on_state, STREAM_QOS)
        self.move = self.node.create_client(MovePtz, "ptz/move_absolute")
        self.center = self.node.create_client(CenterOnPixel, "ptz/center")
        self.set_zoom = self.node.create_client(SetZoom, "ptz/set_zoom")
        self.relative_pub = self.node.create_publisher(PtzCommand, "ptz/cmd/relative", 5)
        self.velocity_pub = self.node.create_publisher(PtzVelocity, "ptz/cmd/velocity", 5)

    def _on_image(self, msg: CompressedImage) -> None:
        with self.lock:
            self.images.append(msg)

    def _on_info(self, msg: CameraInfo) -> None:
        with self.lock:
            self.infos[(msg.header.stamp.sec, msg.header.stamp.nanosec)] = msg

    def _on_state(self, msg: PtzState) -> None:
        self.state = msg

    def _on_tf(self, msg: TransformStamped) -> None:
        with self.lock:
            self.transforms[(msg.header.stamp.sec, msg.header.stamp.nanosec)] = msg
        self.transform = msg

    def _on_joints(self, msg: JointState) -> None:
        with self.lock:
            self.joints_by_stamp[(msg.header.stamp.sec, msg.header.stamp.nanosec)] = msg
        self.joints = msg

    def joints_with_transform(self, pan: float) -> tuple[JointState, TransformStamped] | None:
        """The newest joint state at ``pan`` and the transform published with it (same stamp), if both arrived.

        Topics keep only the newest sample (depth 1), so one stamp's joint state or transform may be replaced
        before it is taken; the head is still, so the next poll's pair serves."""
        with self.lock:
            for key in sorted(self.joints_by_stamp, reverse=True):
                js = self.joints_by_stamp[key]
                if abs(js.position[0] - pan) < 1e-9 and key in self.transforms:
                    return js, self.transforms[key]
        return None

    def publish_panorama(self, bgr: np.ndarray) -> None:
        if self.raw:
            m = Image()
            m.height, m.width = bgr.shape[:2]
            m.encoding = "rgb8"  # exercise the channel swap
            m.step = m.width * 3
            m.data = np.ascontiguousarray(bgr[:, :, ::-1]).tobytes()
        else:
            m = CompressedImage()
            m.format = "bgr8; jpeg compressed bgr8"
            m.data = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, 97])[1].tobytes()
        m.header.frame_id = "panorama_link"
        self.pano_pub.publish(m)

    def frame_after(self, t_ns: int, timeout: float = 5.0) -> tuple[CompressedImage, CameraInfo]:
        """The first image stamped after ``t_ns`` and its camera_info (same stamp)."""

        def find() -> tuple[CompressedImage, CameraInfo] | None:
            with self.lock:
                for im in self.images:
                    st = im.header.stamp
                    if st.sec * 10**9 + st.nanosec > t_ns and (st.sec, st.nanosec) in self.infos:
                        return im, self.infos[(st.sec, st.nanosec)]
            return None

        return self.ros.wait_for(find, timeout)

    def move_abs(self, pan: float, tilt: float, zoom: float) -> MovePtz.Response:
        req = MovePtz.Request()
        req.command = PtzCommand(pan=pan, tilt=tilt, zoom=zoom, speed=math.nan)
        req.wait, req.timeout_s = True, 5.0
        resp = self.ros.call(self.move, req)
        assert resp.success, resp.message
        return resp

    def still_state(self, predicate: Any, timeout: float = 5.0) -> PtzState:
        return self.ros.wait_for(lambda: self.state if self.state and predicate(self.state) else None, timeout)


def start(ros: Any, tmp_path: Path, rpy: tuple[float, float, float], raw: bool = False) -> tuple[Any, Probe]:
    over = [
        Parameter("robot_file", value=robot_file(tmp_path, rpy)),
        Parameter("width", value=W),
        Parameter("height", value=H),
        Parameter("min_rate", value=10.0),
        Parameter("rate", value=30.0),
        Parameter("jpeg_quality", value=95),
        Parameter("panorama_transport", value="raw" if raw else "compressed"),
    ]
    node = VirtualCameraNode(context=ros.context, parameter_overrides=over)
    ros.add(node)
    ros.add(node.ptz)
    probe = Probe(ros, raw)
    return node, probe


def expected_pixel(info: CameraInfo, pan: float, tilt: float, d_base: np.ndarray) -> np.ndarray:
    """K·R⁻¹·d with K from the received camera_info and R = Rz(pan)·Ry(−tilt)·R_body_opt."""
    K = np.array(info.k).reshape(3, 3)
    R = transforms.rot_z(pan) @ transforms.rot_y(-tilt) @ transforms.R_BODY_OPT
    p = K @ (R.T @ d_base)
    return p[:2] / p[2]


def feed_until_decoded(node: VirtualCameraNode, probe: Probe, pano: np.ndarray) -> None:
    def fed() -> bool:  # a panorama every 0.05 s (the wait's period) until one is decoded
        if node.stats.panoramas_decoded > 0:
            return True
        probe.publish_panorama(pano)
        return False

    probe.ros.wait_for(fed, 10.0, period=0.05)


D_MARKER = g.pan_tilt_to_direction(MARKER_PAN, MARKER_TILT)


def test_marker_lands_at_K_R_inv_d_through_the_node(ros, tmp_path):
    """JPEG panorama yawed 54° against base_link; pan/tilt/zoom commanded through ptz/move_absolute."""
    rpy = (0.0, 0.0, math.radians(54.0))
    node, probe = start(ros, tmp_path, rpy)
    R_pano_base = transforms.rpy_to_matrix(*rpy).T
    feed_until_decoded(node, probe, synthetic_panorama(R_pano_base, D_MARKER))

    poses = [  # (pan, tilt, zoom): wide with the marker far off-centre, zoomed in slightly off-centre
        (MARKER_PAN + 0.25, MARKER_TILT - 0.12, 1.0),
        (MARKER_PAN - 0.021, MARKER_TILT + 0.013, 4000.0),
        (MARKER_PAN + 0.3, -0.1, 800.0),
    ]
    zm = node.zoom_model
    for pan, tilt, zoom in poses:
        resp = probe.move_abs(pan, tilt, zoom)
        assert (resp.state.pan, resp.state.tilt, resp.state.zoom) == pytest.approx((pan, tilt, zoom), abs=1e-9)
        image, info = probe.frame_after(time.time_ns())
        # camera_info is the render's K, the zoom model's intrinsics at that zoom (square pixels)
        view = ViewSpec(W, H, pan, tilt, zm.hfov(zoom))
        assert (info.width, info.height) == (W, H)
        assert np.allclose(np.array(info.k).reshape(3, 3), view.intrinsics.K, rtol=1e-12)
        assert np.allclose(np.array(info.k).reshape(3, 3), zm.intrinsics(zoom, W, H).K, rtol=1e-9)
        assert info.header.frame_id == image.header.frame_id == "virtual_camera_optical_frame"
        # ptz/state agrees with the render
        state = probe.still_state(lambda s, z=zoom: not s.moving and abs(s.zoom - z) < 1e-6)
        assert state.hfov == pytest.approx(2 * math.atan((W / 2) / info.k[0]), abs=1e-12)
        assert state.vfov == pytest.approx(2 * math.atan((H / 2) / info.k[4]), abs=1e-12)
        # joint_states and ptz/transform (base_link -> optical frame) describe the rendered view
        js, tf = ros.wait_for(lambda p=pan: probe.joints_with_transform(p))
        assert list(js.name) == ["virtual_camera_pan_joint", "virtual_camera_tilt_joint"]
        assert js.position[1] == pytest.approx(tilt, abs=1e-9)
        assert (tf.header.frame_id, tf.child_frame_id) == ("base_link", "virtual_camera_optical_frame")
        t, q = tf.transform.translation, tf.transform.rotation
        assert (t.x, t.y, t.z) == pytest.approx(T_PANO, abs=1e-12)  # the view's centre is the panorama's
        assert np.allclose(transforms.quaternion_to_matrix(q.x, q.y, q.z, q.w), view.R_base_opt, atol=1e-9)
        exp = expected_pixel(info, pan, tilt, D_MARKER)
        assert exp == pytest.approx(direction_pixel(view, D_MARKER), abs=1e-9)
        assert 30 < exp[0] < W - 30
        assert 30 < exp[1] < H - 30
        got = marker_centroid(bytes(image.data), (exp[0], exp[1]), half=int(8 * SIGMA * info.k[0]) + 4)
        err = math.hypot(got[0] - exp[0], got[1] - exp[1])
        print(
            f"pose ({pan:.3f}, {tilt:.3f}, z {zoom:.0f}): marker at ({got[0]:.3f}, {got[1]:.3f}), "
            f"expected ({exp[0]:.3f}, {exp[1]:.3f}): {err:.3f} px"
        )
        assert err < 0.5


def test_operator_tools_drive_it_unchanged(ros, tmp_path):
    """Raw Image panorama, tilted against base_link (general map path); web console click (ptz/center),
    keyboard teleop step (ptz/cmd/relative), zoom by field of view (ptz/set_zoom), velocity."""
    rpy = (0.03, -0.05, 1.2)
    node, probe = start(ros, tmp_path, rpy, raw=True)
    feed_until_decoded(node, probe, synthetic_panorama(transforms.rpy_to_matrix(*rpy).T, D_MARKER))

    pan0, tilt0, zoom0 = MARKER_PAN + 0.12, MARKER_TILT + 0.07, 1500.0
    probe.move_abs(pan0, tilt0, zoom0)
    image, info = probe.frame_after(time.time_ns())
    click = marker_centroid(bytes(image.data))  # the operator clicks on the marker
    assert click == pytest.approx(tuple(expected_pixel(info, pan0, tilt0, D_MARKER)), abs=0.5)

    # web console: click -> ptz/center (CenterOnPixel, image size 0 = the stream's) -> marker at the centre
    req = CenterOnPixel.Request()
    req.target = PixelTarget(u=click[0], v=click[1], image_width=0, image_height=0, zoom_delta=0.0)
    req.wait, req.timeout_s = True, 5.0
    resp = ros.call(probe.center, req)
    assert resp.success, resp.message
    image, info = probe.frame_after(time.time_ns())
    got = marker_centroid(bytes(image.data))
    print(f"after ptz/center: marker at ({got[0]:.3f}, {got[1]:.3f}), centre ({info.k[2]}, {info.k[5]})")
    assert got == pytest.approx((info.k[2], info.k[5]), abs=0.5)
    pan1, tilt1 = resp.state.pan, resp.state.tilt
    assert (pan1, tilt1) == pytest.approx((MARKER_PAN, MARKER_TILT), abs=0.5 / info.k[0])

    # keyboard teleop: key "a" with step 3 -> RelativeMove(pan=+3°) published on ptz/cmd/relative
    cmds, _ = apply("a", TeleopState(step=3))
    (rel,) = cmds
    probe.relative_pub.publish(PtzCommand(pan=rel.pan, tilt=rel.tilt, zoom=rel.zoom, speed=math.nan))
    target = pan1 + math.radians(3.0)
    probe.still_state(lambda s: not s.moving and abs(s.pan - target) < 1e-9)
    image, info = probe.frame_after(time.time_ns())
    exp = expected_pixel(info, target, tilt1, D_MARKER)
    got = marker_centroid(bytes(image.data), (exp[0], exp[1]))
    print(f"key 'a' (+3 deg): marker at ({got[0]:.3f}, {got[1]:.3f}), expected ({exp[0]:.3f}, {exp[1]:.3f})")
    assert got == pytest.approx(tuple(exp), abs=0.5)
    assert exp[0] > info.k[2] + 0.9 * info.k[0] * math.tan(math.radians(3.0))  # turned left: marker moved right

    # zoom by field of view: camera_info follows exactly
    zreq = SetZoom.Request(zoom=math.nan, magnification=math.nan, hfov=math.radians(30.0), wait=True, timeout_s=5.0)
    zresp = ros.call(probe.set_zoom, zreq)
    assert zresp.success, zresp.message
    image, info = probe.frame_after(time.time_ns())
    assert info.k[0] == pytest.approx((W / 2) / math.tan(math.radians(15.0)), rel=1e-3)  # zoom rounded to units
    exp = expected_pixel(info, target, tilt1, D_MARKER)
    assert marker_centroid(bytes(image.data), (exp[0], exp[1])) == pytest.approx(tuple(exp), abs=0.5)

    # velocity (joystick / web console hold): the view turns, then the node's velocity timeout stops it
    before = probe.state.pan
    probe.velocity_pub.publish(PtzVelocity(pan_rate=-0.5, tilt_rate=0.0, zoom_rate=0.0))
    probe.still_state(lambda s: s.pan < before - 0.05)
    probe.still_state(lambda s: not s.moving, timeout=5.0)


def test_nothing_done_without_subscribers_and_one_decode_per_panorama(ros, tmp_path):
    rpy = (0.0, 0.0, 0.0)
    over = [Parameter("robot_file", value=robot_file(tmp_path, rpy)), Parameter("rate", value=30.0)]
    node = VirtualCameraNode(context=ros.context, parameter_overrides=over)
    ros.add(node)
    ros.add(node.ptz)
    pub_node = ros.probe("vc_pub")
    pub = pub_node.create_publisher(CompressedImage, "panorama/image_raw/compressed", STREAM_QOS)
    pano = synthetic_panorama(np.eye(3), D_MARKER)
    m = CompressedImage(format="jpeg", data=cv2.imencode(".jpg", pano)[1].tobytes())

    def received() -> bool:  # a panorama every 0.05 s (the wait's period) until three arrived
        if node.stats.panoramas_received >= 3:
            return True
        pub.publish(m)
        return False

    ros.wait_for(received, 10.0, period=0.05)
    time.sleep(0.3)  # a window for a (wrong) decode with nobody watching: the thing under test is that none comes
    assert node.stats.panoramas_decoded == 0  # nobody watches: nothing decoded, nothing rendered
    assert node.stats.frames_published == 0
    received_before = node.stats.panoramas_received  # at most the last of these is still pending

    sub_node = ros.probe("vc_sub")
    frames: list[CompressedImage] = []
    sub_node.create_subscription(CompressedImage, "image_raw/compressed", frames.append, STREAM_QOS)
    ros.wait_for(lambda: len(frames) >= 1, 10.0)
    node.backend.velocity(1.0, 0.0, 0.0)  # the view changes every tick
    ros.wait_for(lambda: len(frames) >= 10, 10.0)
    node.backend.velocity(0.0, 0.0, 0.0)
    # one decode, many views: the pending panorama once, plus one per panorama that arrived late (a straggler
    # of the publishing loop); never one per rendered view
    decoded = node.stats.panoramas_decoded
    late = node.stats.panoramas_received - received_before  # read after: a decode follows its reception
    assert 1 <= decoded <= 1 + late, (decoded, late)
    assert node.stats.frames_published >= 10
    print(
        f"render {node.stats.render_s * 1e3:.2f} ms, JPEG {node.stats.encode_s * 1e3:.2f} ms, "
        f"decode {node.stats.decode_s * 1e3:.1f} ms ({PW}x{PH})"
    )

    # the view size is the render's: the PTZ node refuses to be resized
    res = node.ptz.set_parameters([Parameter("image_width", value=1280)])
    assert not res[0].successful
    assert "fixed by the virtual camera" in res[0].reason
