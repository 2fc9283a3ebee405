"""Simulated panorama camera and laser scanner over real DDS: content at the true poses, latching, noise."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from geometry_msgs.msg import TransformStamped
from rclpy.parameter import Parameter
from sensor_msgs.msg import CompressedImage, PointCloud2
from tf2_msgs.msg import TFMessage

from axis_ptz_ros2.nodes.common import LATCHED_QOS, STREAM_QOS
from axis_ptz_ros2.nodes.laser_sim import LaserSim, cloud_points
from axis_ptz_ros2.nodes.panorama_sim import PanoramaSim
from axis_ptz_ros2.nodes.tf_publish import TF_STATIC_QOS
from axis_ptz_ros2.pointing import project_to_panorama
from axis_ptz_ros2.sim.scene import shared_scene
from axis_ptz_ros2.sim.world import load_world
from axis_ptz_ros2.transforms import Transform, quaternion_to_matrix

pytestmark = pytest.mark.ros

WORLD = load_world()


def _tf(msg: TransformStamped) -> Transform:
    q = msg.transform.rotation
    t = msg.transform.translation
    return Transform(quaternion_to_matrix(q.x, q.y, q.z, q.w), np.array([t.x, t.y, t.z]))


def _mean_colour_in_quad(img, quad):
    mask = np.zeros(img.shape[:2], np.uint8)
    cv2.fillConvexPoly(mask, np.round(quad).astype(np.int32), 255)
    assert mask.sum() > 0
    return img[mask > 0].reshape(-1, 3).mean(axis=0)


def test_panorama_shows_the_scene_from_its_own_pose_and_every_frame_is_new(ros):
    W = 1024
    ros.add(PanoramaSim(context=ros.context, parameter_overrides=[Parameter("width", value=W)]))
    probe = ros.probe()
    frames: list[CompressedImage] = []
    tfs: list[TransformStamped] = []
    probe.create_subscription(CompressedImage, "panorama/image_raw/compressed", frames.append, STREAM_QOS)
    probe.create_subscription(TransformStamped, "panorama/transform", tfs.append, LATCHED_QOS)
    static: list[TFMessage] = []
    probe.create_subscription(TFMessage, "/tf_static", static.append, TF_STATIC_QOS)
    ros.wait_for(lambda: len(frames) >= 3 and tfs and static, timeout=20)

    # Latched pose = the simulated world's true panorama pose, the same message on /tf_static.
    tf = tfs[0]
    assert (tf.header.frame_id, tf.child_frame_id) == ("base_link", "panorama_link")
    T = _tf(tf)
    np.testing.assert_allclose(T.matrix(), WORLD.T_base_pano.matrix(), atol=1e-9)
    assert list(static[-1].transforms) == [tf]

    a, b = frames[-2], frames[-1]
    assert a.header.frame_id == "panorama_link"
    assert (b.header.stamp.sec, b.header.stamp.nanosec) > (a.header.stamp.sec, a.header.stamp.nanosec)
    assert bytes(a.data) != bytes(b.data)  # never the same bytes under a new stamp
    ia = cv2.imdecode(np.frombuffer(bytes(a.data), np.uint8), cv2.IMREAD_COLOR)
    ib = cv2.imdecode(np.frombuffer(bytes(b.data), np.uint8), cv2.IMREAD_COLOR)
    assert ia.shape == (W // 2, W, 3)
    diff = np.abs(ia.astype(int) - ib.astype(int)).max(axis=2)
    ys, xs = np.nonzero(diff > 8)
    assert ys.size > 0
    assert ys.min() >= W // 2 - 48  # the frames differ only in the clock overlay at the bottom-left
    assert xs.max() < W // 3

    # The green side marker (3 m to the left) is where the panorama centre sees it, not where the PTZ head
    # would (8 deg of parallax apart at this range).
    marker = shared_scene(WORLD).target("side_marker")
    quad = project_to_panorama(marker.corners(), WORLD.T_base_pano, W, W // 2)
    b_, g_, r_ = _mean_colour_in_quad(ib, quad)
    assert g_ - max(b_, r_) > 60, (b_, g_, r_)
    T_from_ptz = Transform(np.eye(3), WORLD.pan_tilt_centre)
    quad_ptz = project_to_panorama(marker.corners(), T_from_ptz, W, W // 2)
    assert abs(quad_ptz[:, 0].mean() - quad[:, 0].mean()) > 15  # pixels: the test discriminates
    b2, g2, r2 = _mean_colour_in_quad(ib, quad_ptz)
    assert g2 - max(b2, r2) < g_ - max(b_, r_) - 30


def _classify(points_base, scene):
    """Per point: index of the target plane it lies on (within its rectangle), -2 ground, -9 none."""
    label = np.full(points_base.shape[0], -9)
    label[np.abs(points_base[:, 2]) < 2e-3] = -2
    for i, t in enumerate(scene.targets):
        rel = points_base - t.center
        on_plane = np.abs(rel @ t.normal) < 2e-3
        inside = (np.abs(rel @ t.right) <= t.width / 2 + 1e-3) & (np.abs(rel @ t.up) <= t.height / 2 + 1e-3)
        label[on_plane & inside] = i
    return label


def test_laser_cloud_lies_on_the_ground_and_the_targets_at_their_true_positions(ros):
    ros.add(LaserSim(context=ros.context))
    probe = ros.probe()
    clouds: list[PointCloud2] = []
    tfs: list[TransformStamped] = []
    # Subscribe after the node published its first scan: the latched cloud still arrives.
    probe.create_subscription(PointCloud2, "laser/points", clouds.append, LATCHED_QOS)
    probe.create_subscription(TransformStamped, "laser/transform", tfs.append, LATCHED_QOS)
    static: list[TFMessage] = []
    probe.create_subscription(TFMessage, "/tf_static", static.append, TF_STATIC_QOS)
    ros.wait_for(lambda: clouds and tfs and static, timeout=15)
    assert list(static[-1].transforms) == [tfs[0]]  # the scanner pose on /tf_static too
    assert (tfs[0].header.frame_id, tfs[0].child_frame_id) == ("base_link", "laser_link")
    msg = clouds[0]
    assert msg.header.frame_id == "laser_link"
    assert [f.name for f in msg.fields] == ["x", "y", "z", "intensity"]
    assert msg.point_step == 16
    assert msg.width * msg.height > 10000
    pts = cloud_points(msg)
    T = _tf(tfs[0])
    np.testing.assert_allclose(T.matrix(), WORLD.T_base_laser.matrix(), atol=1e-9)
    xyz = pts[:, :3].astype(np.float64)
    r = np.linalg.norm(xyz, axis=1)
    assert r.min() >= 0.3 - 1e-5
    assert r.max() <= 30.0 + 1e-4
    el = np.degrees(np.arcsin(xyz[:, 2] / r))
    assert el.min() >= -30.0 - 1e-3
    assert el.max() <= 30.0 + 1e-3
    assert np.all((pts[:, 3] >= 0) & (pts[:, 3] <= 1))

    scene = shared_scene(WORLD)
    P = T.apply(xyz)
    label = _classify(P, scene)
    # float32 storage of points up to 30 m away: ~2 µm; every return is on the ground or a target.
    assert np.all(label != -9), P[label == -9][:5]
    names = {scene.targets[i].name for i in np.unique(label[label >= 0])}
    assert {"calib_front", "person_board", "side_marker", "checker_board"} <= names
    # The ground ring 5 m around base_link is in the cloud at its true distance (ground returns only).
    g = P[label == -2]
    assert np.any(np.abs(np.hypot(g[:, 0], g[:, 1]) - 5.0) < 0.05)
    # Ground returns: range = h / sin(-elevation) from the scanner height.
    gi = np.flatnonzero(label == -2)
    h = WORLD.T_base_laser.t[2]
    np.testing.assert_allclose(r[gi], h / np.sin(np.radians(-el[gi])), rtol=1e-4)


def test_laser_range_noise_is_gaussian_with_the_configured_sigma(ros):
    sigma = 0.05
    ros.add(
        LaserSim(
            context=ros.context,
            parameter_overrides=[Parameter("range_noise", value=sigma), Parameter("rate", value=5.0)],
        )
    )
    probe = ros.probe()
    clouds: list[PointCloud2] = []
    probe.create_subscription(PointCloud2, "laser/points", clouds.append, LATCHED_QOS)
    ros.wait_for(lambda: len(clouds) >= 2, timeout=15)
    a, b = cloud_points(clouds[-2]), cloud_points(clouds[-1])
    assert a.shape == b.shape
    ra = np.linalg.norm(a[:, :3].astype(np.float64), axis=1)
    rb = np.linalg.norm(b[:, :3].astype(np.float64), axis=1)
    # Directions are exact; independent noise per scan: var(ra - rb) = 2 sigma^2 (clipping at the range
    # limits aside).
    d = ra - rb
    mid = (ra > 1.0) & (ra < 29.0) & (rb > 1.0) & (rb < 29.0)
    assert math.isclose(float(np.std(d[mid])) / math.sqrt(2), sigma, rel_tol=0.05)
    ua = a[:, :3] / ra[:, None]
    ub = b[:, :3] / rb[:, None]
    assert float(np.max(np.abs(ua - ub))) < 1e-5


def test_laser_fixed_noise_does_not_depend_on_which_scan_a_consumer_takes(ros):
    """With ``noise_per_scan`` false the noise is a function of ``seed`` and ``range_noise`` alone: a consumer
    gets the same cloud whenever it takes a scan. (The calibration capture takes the first scan after the head
    stopped, whose number since start depends on timing: with per-scan noise, one seed gave other clouds, so other
    calibrations, run to run.) A live change of ``seed`` publishes a scan with the new noise at once."""
    noisy = [Parameter("range_noise", value=0.02), Parameter("noise_per_scan", value=False)]
    early = ros.add(
        LaserSim(context=ros.context, namespace="early", parameter_overrides=[*noisy, Parameter("seed", value=7)])
    )
    probe = ros.probe()
    got: dict[str, list[PointCloud2]] = {"early": [], "late": []}
    for ns, clouds in got.items():
        probe.create_subscription(PointCloud2, f"/{ns}/laser/points", clouds.append, LATCHED_QOS)
    ros.wait_for(lambda: len(got["early"]) >= 2, timeout=15)  # its first scan and a later one (1 Hz)
    # A node started later with another seed, scanning every 20 s: only its first scan and the one a live
    # change publishes arrive here.
    late = ros.add(
        LaserSim(
            context=ros.context,
            namespace="late",
            parameter_overrides=[*noisy, Parameter("seed", value=8), Parameter("rate", value=0.05)],
        )
    )
    ros.wait_for(lambda: got["late"], timeout=15)
    a = cloud_points(got["early"][0])
    assert not np.array_equal(cloud_points(got["late"][0]), a)  # another seed, other noise
    assert late.set_parameters([Parameter("seed", value=7)])[0].successful
    ros.wait_for(lambda: len(got["late"]) >= 2, timeout=5)  # published at once, not at the next period
    for msg in got["early"][1:] + got["late"][1:]:
        np.testing.assert_array_equal(cloud_points(msg), a)
    # and the noise is there: σ 2 cm against the exact ranges
    r = np.linalg.norm(a[:, :3].astype(np.float64), axis=1)
    r0 = np.linalg.norm(early._returns.points(), axis=1)  # noqa: SLF001 - the exact ranges it traced
    mid = (r0 > 1.0) & (r0 < 29.0)
    assert math.isclose(float(np.std(r[mid] - r0[mid])), 0.02, rel_tol=0.05)
