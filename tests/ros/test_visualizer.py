"""axis_visualizer over real DDS: the red look-point lands where the PTZ looks, seen from the panorama."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import cv2
import numpy as np
import pytest
from geometry_msgs.msg import TransformStamped
from rclpy.parameter import Parameter
from sensor_msgs.msg import CompressedImage

from axis_ptz_interfaces.msg import PtzState
from axis_ptz_ros2.config import MountConfig, save_mount
from axis_ptz_ros2.nodes.common import LATCHED_QOS, STREAM_QOS, transform_msg
from axis_ptz_ros2.nodes.visualizer import Visualizer
from axis_ptz_ros2.transforms import Transform, rot_z
from tests.support.panorama_expect import H_TILT, PANO, PTZ_BASE, H, W, expected_pixel  # noqa: E402

pytestmark = pytest.mark.ros


def _grey_panorama() -> CompressedImage:
    img = np.full((H, W, 3), 128, np.uint8)
    m = CompressedImage()
    m.header.frame_id = "panorama_link"
    m.format = "jpeg"
    m.data = cv2.imencode(".jpg", img)[1].tobytes()
    return m


def _state(pan: float, tilt: float, zoom: float = 1.0) -> PtzState:
    s = PtzState()
    s.header.frame_id = "axis_ptz_base"
    s.pan, s.tilt, s.zoom = pan, tilt, zoom
    s.hfov = math.radians(47.98)
    s.vfov = 2 * math.atan(math.tan(s.hfov / 2) * (576 / 704) * (4 / 3))
    return s


def _mask(img, bgr):
    b, g, r = (img[..., i].astype(int) for i in range(3))
    if bgr == "red":
        return (r > 170) & (g < 90) & (b < 90)
    return (r > 170) & (g > 170) & (b < 90)  # yellow


class _Rig:
    def __init__(self, ros, overrides=()):
        self.ros = ros
        self.node = ros.add(Visualizer(context=ros.context, parameter_overrides=list(overrides)))
        self.probe = ros.probe("viz_probe")
        self.pano_pub = self.probe.create_publisher(CompressedImage, "panorama/image_raw/compressed", STREAM_QOS)
        self.state_pub = self.probe.create_publisher(PtzState, "ptz/state", STREAM_QOS)
        self.tf_pub = self.probe.create_publisher(TransformStamped, "ptz/transform", STREAM_QOS)
        self.out: list[CompressedImage] = []

    def subscribe(self):
        self.probe.create_subscription(CompressedImage, "axis_visualizer/compressed", self.out.append, STREAM_QOS)
        self.ros.wait_for(lambda: self.node._pub.get_subscription_count() > 0)

    def frame_after(self, publish):
        """Publish until a frame drawn from the new inputs arrives; return it decoded."""
        n0 = self.node.frames_published

        def got():
            publish()
            return self.node.frames_published > n0 + 1 and len(self.out) > 0

        self.ros.wait_for(got, timeout=10, period=0.1)
        return cv2.imdecode(np.frombuffer(bytes(self.out[-1].data), np.uint8), cv2.IMREAD_COLOR)


def timer_fired(timer: Any, times: int) -> Callable[[], bool]:
    """A condition: ``timer`` has been called ``times`` times since this was made (each call restarts its
    ``time_since_last_call``; polled far more often than its period, so none is missed)."""
    state = {"last": timer.time_since_last_call(), "fired": 0}

    def fired() -> bool:
        since = timer.time_since_last_call()
        if since < state["last"]:
            state["fired"] += 1
        state["last"] = since
        return state["fired"] >= times

    return fired


def test_red_mark_lands_on_the_ptz_look_point_seen_from_the_panorama(ros):
    rig = _Rig(ros, [Parameter("depth", value=5.0)])
    pano = _grey_panorama()
    rig.pano_pub.publish(pano)
    rig.state_pub.publish(_state(0.6, 0.2))
    rig.ros.wait_for(lambda: rig.node._state is not None and rig.node._pano_msg is not None)
    # Nobody subscribed yet: nothing is encoded, however many times its timer fires.
    rig.ros.wait_for(timer_fired(rig.node._timer, 4), timeout=10)  # noqa: SLF001 - the node's one timer
    assert rig.node.frames_published == 0
    rig.subscribe()
    for pan, tilt, depth in ((0.6, 0.2, 5.0), (-1.2, -0.3, 5.0), (0.6, 0.2, 1.0)):
        rig.node.set_parameters([Parameter("depth", value=depth)])
        img = rig.frame_after(lambda p=pan, t=tilt: (rig.pano_pub.publish(pano), rig.state_pub.publish(_state(p, t))))
        assert img.shape == (H, W, 3)
        ys, xs = np.nonzero(_mask(img, "red"))
        assert xs.size > 20
        ex, ey = expected_pixel(pan, tilt, depth)
        assert abs(xs.mean() - ex) < 1.5, (xs.mean(), ex)
        assert abs(ys.mean() - ey) < 1.5, (ys.mean(), ey)
        # The naive thesis mapping (PTZ pan/tilt as panorama az/el) would put it elsewhere at 1 m.
        if depth == 1.0:
            naive_x = (0.5 - pan / (2 * math.pi)) * W - 0.5
            assert abs(xs.mean() - naive_x) > 10
        # The yellow footprint surrounds the mark: about one HFOV (48 deg ~ 136 px at W=1024) wide.
        fy, fx = np.nonzero(_mask(img, "yellow"))
        assert fx.size > 50
        assert fx.min() < ex - 40 < ex + 40 < fx.max()
        assert fy.min() < ey < fy.max()


def test_ptz_transform_wins_and_the_footprint_wraps_at_the_seam(ros):
    rig = _Rig(ros, [Parameter("depth", value=10.0)])
    pano = _grey_panorama()
    rig.subscribe()
    # An optical frame looking straight back (-x of base_link) from 1 m above base_link: the look point is
    # at the seam (azimuth pi), so the mark and the footprint appear at both image edges.
    R_back = rot_z(math.pi) @ np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    T = Transform(R_back, np.array([0.216, -0.044, 1.0]))
    tf = transform_msg(T, "base_link", "axis_ptz_optical_frame", rig.probe.get_clock().now().to_msg())

    def pub():
        rig.pano_pub.publish(pano)
        rig.state_pub.publish(_state(0.0, 0.0))  # contradicts the transform: the transform must win
        rig.tf_pub.publish(tf)

    img = rig.frame_after(pub)
    ys, xs = np.nonzero(_mask(img, "red"))
    assert xs.size > 10
    assert xs.min() < 8
    assert xs.max() > W - 9  # split circle at both edges
    assert np.all((xs < 20) | (xs > W - 21))
    el = math.atan2(1.0 - 0.75, 10.0)
    assert abs(ys.mean() - ((0.5 - el / math.pi) * H - 0.5)) < 1.5
    fy, fx = np.nonzero(_mask(img, "yellow"))
    assert np.any(fx < 30)
    assert np.any(fx > W - 31)
    assert not np.any((fx > 200) & (fx < W - 200))  # no line drawn across the whole panorama


def test_latched_panorama_transform_is_used(ros):
    rig = _Rig(ros, [Parameter("depth", value=5.0)])
    pano = _grey_panorama()
    # A panorama frame yawed by +90 deg (as TRADR's was yawed by 54 deg): azimuths shift by -90 deg.
    T_pano = Transform(rot_z(math.pi / 2), PANO.copy())
    latched = rig.probe.create_publisher(TransformStamped, "panorama/transform", LATCHED_QOS)
    latched.publish(transform_msg(T_pano, "base_link", "panorama_link", rig.probe.get_clock().now().to_msg()))
    rig.subscribe()
    img = rig.frame_after(lambda: (rig.pano_pub.publish(pano), rig.state_pub.publish(_state(0.0, 0.0))))
    ys, xs = np.nonzero(_mask(img, "red"))
    ex, _ = expected_pixel(0.0, 0.0, 5.0)
    shifted = ex + W / 4  # azimuth -90 deg in the yawed panorama = a quarter width to the right
    assert abs(xs.mean() - shifted) < 1.5


def test_auto_depth_uses_the_ground_when_there_is_no_laser(ros):
    rig = _Rig(ros, [Parameter("depth", value=50.0), Parameter("auto_depth", value=True)])
    pano = _grey_panorama()
    rig.subscribe()
    pan, tilt = 0.4, -0.3
    img = rig.frame_after(lambda: (rig.pano_pub.publish(pano), rig.state_pub.publish(_state(pan, tilt))))
    ys, xs = np.nonzero(_mask(img, "red"))
    ground = (PTZ_BASE[2] + H_TILT) / math.sin(-tilt)  # range along the axis to z = 0
    ex, ey = expected_pixel(pan, tilt, ground)
    assert abs(xs.mean() - ex) < 1.5
    assert abs(ys.mean() - ey) < 1.5
    far_x, far_y = expected_pixel(pan, tilt, 50.0)
    assert math.hypot(far_x - ex, far_y - ey) > 10  # the fixed depth would be visibly elsewhere


def test_state_is_in_joint_coordinates_so_mount_offsets_are_not_added_again(ros, tmp_path):
    """ptz/state carries joint angles (the PTZ node adds the mount's encoder offsets to the head's reading,
    ptz.control.JointOffsets.from_head), the frame the kinematics take: a mount with non-zero offsets must draw
    the mark where the nominal mount does (the shipped mount has zero offsets, which would hide a double add)."""
    mount = MountConfig(transform=Transform.from_xyz_rpy(*PTZ_BASE, 0.0, 0.0, 0.0), pan_offset=0.35, tilt_offset=-0.12)
    path = tmp_path / "mount_offsets.yaml"
    save_mount(mount, path)
    rig = _Rig(ros, [Parameter("depth", value=5.0), Parameter("mount_file", value=str(path))])
    assert rig.node.overlay.mount.pan_offset == pytest.approx(0.35)  # the file was really used
    pano = _grey_panorama()
    rig.subscribe()
    pan, tilt = 0.6, 0.2
    img = rig.frame_after(lambda: (rig.pano_pub.publish(pano), rig.state_pub.publish(_state(pan, tilt))))
    ys, xs = np.nonzero(_mask(img, "red"))
    assert xs.size > 20
    ex, ey = expected_pixel(pan, tilt, 5.0)
    assert abs(xs.mean() - ex) < 1.5, (xs.mean(), ex)
    assert abs(ys.mean() - ey) < 1.5, (ys.mean(), ey)
