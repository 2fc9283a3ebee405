"""Automatic picking on the simulated calibration boards, and the ROS-free helpers of the capture tool.

Image-side checks compare detections with the TRUE projection of the boards' dots (simulator renderer, true
mount); the picking code itself only ever sees a guessed (nominal) mount.
"""

from __future__ import annotations

import math
from dataclasses import replace

import cv2
import numpy as np
import pytest

from axis_ptz_ros2.calibration.capture import (
    CapturedView,
    CaptureError,
    cloud_in_base,
    cloud_path,
    parse_pose6,
    parse_poses,
    still_view,
    store_view,
    transform_cloud,
    views_dir,
)
from axis_ptz_ros2.calibration.correspondences import CorrespondenceError, load_correspondences
from axis_ptz_ros2.calibration.picking import (
    Feature,
    associate_dots,
    detect_dots,
    fit_plane,
    pick_laser_point,
    pick_view,
    picking_noise,
)
from axis_ptz_ros2.calibration.synthetic import default_camera_model
from axis_ptz_ros2.config import load_mount
from axis_ptz_ros2.pointcloud import CloudField, decode_cloud
from axis_ptz_ros2.sim.ptz import ros_to_vapix
from axis_ptz_ros2.sim.renderer import PtzRenderer, encode_jpeg
from axis_ptz_ros2.sim.scene import shared_scene
from axis_ptz_ros2.sim.world import load_world
from axis_ptz_ros2.transforms import Transform, rot_z
from tests.support.sim_picker import scene_dot_features

pytestmark = pytest.mark.unit

W, H = 704, 576
WORLD = load_world()
NOMINAL = load_mount().transform  # what the picking may use as a guess (not the truth)


@pytest.fixture(scope="module")
def renderer() -> PtzRenderer:
    return PtzRenderer(WORLD, shared_scene(WORLD))


def _view(renderer: PtzRenderer, pan_deg: float, tilt_deg: float, zoom: float) -> np.ndarray:
    """The simulated camera's frame (through JPEG, like the stream) at a REP-103 pose in degrees."""
    pv, tv = ros_to_vapix(math.radians(pan_deg), math.radians(tilt_deg))
    jpeg = encode_jpeg(renderer.render(pv, tv, zoom, W, H), 30)
    return cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR)


def _true_uv(renderer: PtzRenderer, pan_deg: float, tilt_deg: float, zoom: float, point) -> np.ndarray:
    pv, tv = ros_to_vapix(math.radians(pan_deg), math.radians(tilt_deg))
    T = renderer.camera_pose(pv, tv)
    K = WORLD.zoom_model.intrinsics(zoom, W, H)
    return K.project(T.inverse().apply(np.asarray(point, float))[None])[0]


def _scan(step_deg: float = 0.5) -> np.ndarray:
    """A laser scan like axis_laser_sim's (elevation ±30°, full turn), as (N, 4) x y z intensity in base_link."""
    st = math.radians(step_deg)
    el = np.arange(-math.radians(30), math.radians(30) + 1e-9, st)
    az = -math.pi + st * np.arange(int(round(2 * math.pi / st)))
    E, A = np.meshgrid(el, az, indexing="ij")
    d = np.stack([np.cos(E) * np.cos(A), np.cos(E) * np.sin(A), np.sin(E)], -1).reshape(-1, 3)
    T = WORLD.T_base_laser
    bgr, depth, _ = shared_scene(WORLD).raycast(T.t, d @ T.R.T)
    ok = np.isfinite(depth) & (depth < 30.0)
    pts = T.apply(d[ok] * depth[ok, None])
    lum = bgr[ok].astype(float) @ np.array([0.114, 0.587, 0.299]) / 255.0
    return np.column_stack([pts, lum])


@pytest.fixture(scope="module")
def cloud() -> np.ndarray:
    return _scan()


# ------------------------------------------------------------------------------------------------------
# image side
# ------------------------------------------------------------------------------------------------------
def test_dots_found_with_subpixel_accuracy_on_two_boards(renderer):
    pan, tilt, zoom = 25.0, 7.0, 1.0
    img = _view(renderer, pan, tilt, zoom)
    dots = detect_dots(img)
    feats = scene_dot_features(shared_scene(WORLD))
    K = WORLD.zoom_model.intrinsics(zoom, W, H)
    cm = replace(default_camera_model(), head=WORLD.kinematics)
    guess = NOMINAL @ cm.head.optical_in_ptz_base(math.radians(pan), math.radians(tilt))
    pairs = associate_dots(dots, feats, guess, K)
    labels = sorted(f.label for _, f in pairs)
    assert labels == sorted(
        f"{b}/dot_{c}" for b in ("calib_front", "calib_left") for c in ("red", "green", "blue", "yellow")
    )
    errs = [np.hypot(*(np.array([d.u, d.v]) - _true_uv(renderer, pan, tilt, zoom, f.point))) for d, f in pairs]
    assert max(errs) < 0.8, errs  # sub-pixel against the true projection
    assert np.sqrt(np.mean(np.square(errs))) < 0.5


def test_zoomed_view_and_colour_rejections(renderer):
    # Zoomed in on calib_right: four big dots, still sub-pixel.
    pan, tilt, zoom = -38.5, 0.8, 1200.0
    img = _view(renderer, pan, tilt, zoom)
    dots = detect_dots(img)
    assert sorted(d.colour for d in dots) == ["blue", "green", "red", "yellow"]
    feats = [f for f in scene_dot_features(shared_scene(WORLD)) if f.label.startswith("calib_right/")]
    for d in dots:
        f = next(f for f in feats if f.colour == d.colour)
        assert np.hypot(*(np.array([d.u, d.v]) - _true_uv(renderer, pan, tilt, zoom, f.point))) < 1.0
    # Dots cut by the image border (red above yellow on the left) are rejected, the others are kept.
    red = next(d for d in dots if d.colour == "red")
    kept = detect_dots(img[:, int(red.u) :].copy())
    assert sorted(d.colour for d in kept) == ["blue", "green"]
    # The ground's red 5 m ring, green/yellow lit windows and ground marks are not dots.
    ground = _view(renderer, 0.0, -25.0, 1.0)
    assert detect_dots(ground) == []
    assert detect_dots(_view(renderer, 180.0 - 60.0, 2.0, 1.0)) == []


def test_association_uses_the_guess_and_refuses_far_or_ambiguous():
    feats = [
        Feature("a/dot_red", "red", (4.0, 0.0, 0.0)),
        Feature("b/dot_red", "red", (4.0, 0.7, 0.0)),  # 10° to the left
        Feature("a/dot_blue", "blue", (4.0, -0.2, 0.0)),
    ]
    cm = default_camera_model()
    K = cm.zoom.intrinsics(1.0, W, H)
    T_opt = cm.head.optical_in_ptz_base(0.0, 0.0)
    T_opt = Transform(T_opt.R, np.zeros(3))
    from axis_ptz_ros2.calibration.picking import Dot

    def at(p):
        return K.project(T_opt.inverse().apply(np.array(p, float))[None])[0]

    u, v = at(feats[0].point)
    dots = [Dot("red", u + 10, v - 5, 100, 1.0), Dot("blue", *at(feats[2].point), 100, 1.0)]
    # The guess is 1.5° off in yaw: still the right features.
    guess = Transform(rot_z(math.radians(1.5)) @ T_opt.R, T_opt.t)
    got = {d.colour: f.label for d, f in associate_dots(dots, feats, guess, K)}
    assert got == {"red": "a/dot_red", "blue": "a/dot_blue"}
    # Beyond the gate: no pair rather than a wrong one.
    far = Transform(rot_z(math.radians(6.0)) @ T_opt.R, T_opt.t)
    assert associate_dots(dots, feats, far, K, max_angle_deg=3.0) == []
    # Two same-colour candidates close together: ambiguous, dropped.
    twins = [feats[0], Feature("c/dot_red", "red", (4.0, 0.05, 0.0))]
    assert associate_dots(dots[:1], twins, T_opt, K) == []


# ------------------------------------------------------------------------------------------------------
# laser side
# ------------------------------------------------------------------------------------------------------
def test_laser_picking_noise_against_truth(cloud):
    feats = [f for f in scene_dot_features(shared_scene(WORLD)) if not f.label.startswith("zoom_ref")]
    truth = [f.point for f in feats]
    stats = {
        m: picking_noise([pick_laser_point(cloud, f.point, mode=m).point for f in feats], truth)
        for m in ("nearest", "plane", "blob")
    }
    print({m: (round(s.rms * 100, 2), round(s.max * 100, 2)) for m, s in stats.items()})
    # 0.5° scan at ~4 m: points 3.5 cm apart, the nearest one is up to ~2.5 cm off.
    assert 0.005 < stats["nearest"].rms < 0.025
    assert stats["nearest"].max < 0.035
    # The blob centroid on the board plane is several times better.
    assert stats["blob"].rms < 0.5 * stats["nearest"].rms
    assert stats["blob"].max < 0.02
    for f in feats:
        assert pick_laser_point(cloud, f.point, mode="blob").mode == "blob"


def test_plane_refinement_removes_range_noise():
    rng = np.random.default_rng(3)
    # A board in the plane x = 3 with a dark disk of radius 6.4 cm at (y, z) = (0.2, 1.0).
    yy, zz = np.meshgrid(np.arange(-0.2, 0.6, 0.03), np.arange(0.7, 1.3, 0.03))
    pts = np.column_stack([np.full(yy.size, 3.0), yy.ravel(), zz.ravel()])
    on_dot = np.hypot(pts[:, 1] - 0.2, pts[:, 2] - 1.0) < 0.064
    inten = np.where(on_dot, 0.3, 0.9)
    noisy = pts + np.column_stack([rng.normal(0, 0.01, len(pts)), np.zeros((len(pts), 2))])
    cloud = np.column_stack([noisy, inten])
    n, d = fit_plane(noisy)
    assert abs(abs(n[0]) - 1.0) < 1e-3
    assert abs(abs(d) - 3.0) < 0.01
    truth = (3.0, 0.2, 1.0)
    near = pick_laser_point(cloud, truth, mode="nearest")
    plane = pick_laser_point(cloud, truth, mode="plane")
    blob = pick_laser_point(cloud, truth, mode="blob")
    assert plane.mode == "plane"
    assert blob.mode == "blob"
    assert blob.n_support >= 10
    # The clicked point carries its range noise, the plane fit removes it (over a few clicks on the board).
    clicks = [(3.0, y, z) for y in (0.0, 0.1, 0.3) for z in (0.8, 0.9, 1.1)]
    near_err = [abs(pick_laser_point(cloud, c, mode="nearest").point[0] - 3.0) for c in clicks]
    plane_err = [abs(pick_laser_point(cloud, c, mode="plane").point[0] - 3.0) for c in clicks]
    assert np.mean(near_err) > 0.005
    assert np.mean(plane_err) < 0.003
    assert abs(plane.point[0] - 3.0) < 0.004
    assert abs(blob.point[0] - 3.0) < 0.004
    # In the plane the blob centroid beats the nearest grid point (1 cm off here), limited by the 3 cm grid.
    assert np.hypot(blob.point[1] - 0.2, blob.point[2] - 1.0) < 0.75 * np.hypot(
        near.point[1] - 0.2, near.point[2] - 1.0
    )
    # Without intensity the blob mode cannot work and says so.
    with pytest.raises(ValueError, match="intensity"):
        pick_laser_point(noisy, truth, mode="blob")


def test_pick_view_end_to_end_without_ros(renderer, cloud):
    pan, tilt, zoom = 25.0, 7.0, 1.0
    img = _view(renderer, pan, tilt, zoom)
    cm = replace(default_camera_model(), head=WORLD.kinematics)
    feats = scene_dot_features(shared_scene(WORLD))
    picked = pick_view(img, cloud, math.radians(pan), math.radians(tilt), zoom, feats, cm, NOMINAL)
    assert len(picked) == 8
    noise = picking_noise([p.laser.point for p in picked], [p.feature.point for p in picked])
    assert noise.max < 0.02
    c = picked[0].correspondence()
    assert c.label == picked[0].feature.label
    assert c.pixel == (picked[0].dot.u, picked[0].dot.v)


# ------------------------------------------------------------------------------------------------------
# capture helpers (ROS-free)
# ------------------------------------------------------------------------------------------------------
def test_parse_poses_and_laser_pose():
    p = parse_poses("25,7,1; -38.5,0.8 ;12.7,7.5,1200;")
    assert len(p) == 3
    assert p[0].pan == pytest.approx(math.radians(25))
    assert p[0].zoom == 1
    assert math.isnan(p[1].zoom)
    for bad, msg in (("25", "expected"), ("a,b", "not a number"), ("400,0", "within"), ("", "no poses")):
        with pytest.raises(ValueError, match=msg):
            parse_poses(bad)
    T = parse_pose6("0.25,0,0.4,0,0,90")
    np.testing.assert_allclose(T.apply([1.0, 0.0, 0.0]), [0.25, 1.0, 0.4], atol=1e-12)


def test_decode_cloud_layouts_and_transform():
    pts = np.array([[1.0, 2.0, 3.0, 0.5], [4.0, 5.0, 6.0, 0.25], [np.nan, 0, 0, 1]], "<f4")
    fields = [CloudField(n, 4 * i, 7) for i, n in enumerate(["x", "y", "z", "intensity"])]
    out = decode_cloud(pts.tobytes(), fields, 16, 3)
    np.testing.assert_allclose(out, pts[:2])
    # Padded, big-endian float64 without intensity (point_step 32).
    arr = np.zeros(
        2, dtype=np.dtype({"names": ["x", "y", "z"], "formats": [">f8"] * 3, "offsets": [0, 8, 16], "itemsize": 32})
    )
    arr["x"], arr["y"], arr["z"] = [1, 2], [3, 4], [5, 6]
    out = decode_cloud(arr.tobytes(), [CloudField(n, 8 * i, 8) for i, n in enumerate("xyz")], 32, 2, True)
    np.testing.assert_allclose(out[:, :3], [[1, 3, 5], [2, 4, 6]])
    assert np.isnan(out[:, 3]).all()
    with pytest.raises(ValueError, match="'z'"):
        decode_cloud(pts.tobytes(), fields[:2], 16, 3)
    with pytest.raises(ValueError, match="too short"):
        decode_cloud(pts.tobytes()[:20], fields, 16, 3)
    T = Transform.from_xyz_rpy(0.25, 0.0, 0.4, 0, 0, math.pi / 2)
    moved = transform_cloud(np.array([[1.0, 0.0, 0.0, 0.7]]), T)
    np.testing.assert_allclose(moved, [[0.25, 1.0, 0.4, 0.7]], atol=1e-12)


def test_store_view_writes_image_cloud_and_appends(tmp_path):
    out = tmp_path / "calib.yaml"
    ok, jpeg = cv2.imencode(".jpg", np.full((H, W, 3), 200, np.uint8))
    assert ok
    cap = CapturedView("v0", 0.1, -0.05, 1.0, jpeg.tobytes(), W, H, np.array([[1.0, 2.0, 3.0, 0.5]]))
    view = store_view(out, cap, camera_model="model.yaml", ply=True)
    assert view.image == "calib_views/v0.jpg"
    assert (views_dir(out) / "v0.jpg").read_bytes() == jpeg.tobytes()
    cs = load_correspondences(out)
    assert cs.views[0].name == "v0"
    assert cs.views[0].points == ()
    assert cs.camera_model == "model.yaml"
    saved = np.load(cloud_path(out, cs.views[0]))
    np.testing.assert_allclose(saved, [[1.0, 2.0, 3.0, 0.5]])
    ply = (views_dir(out) / "v0.ply").read_text(encoding="ascii").splitlines()
    assert ply[:3] == ["ply", "format ascii 1.0", "element vertex 1"]
    assert "property float intensity" in ply
    assert [float(x) for x in ply[-1].split()] == [1.0, 2.0, 3.0, 0.5]
    with pytest.raises(CorrespondenceError, match="already exists"):
        store_view(out, cap)
    with pytest.raises(CorrespondenceError, match="letters"):
        store_view(out, CapturedView("../x", 0.0, 0.0, 1.0, b"", W, H, np.zeros((0, 4))))


def _state(pan: float, tilt: float, zoom: float = 1.0, moving: bool = False):
    import types

    return types.SimpleNamespace(pan=pan, tilt=tilt, zoom=zoom, moving=moving)


def test_a_still_view_is_the_median_pose_minus_the_encoder_offsets_and_refuses_motion():
    ok, jpeg = cv2.imencode(".jpg", np.full((H, W, 3), 90, np.uint8))
    assert ok
    cloud = np.array([[1.0, 2.0, 3.0, 0.5]])
    states = [_state(0.30, -0.10, 900.0), _state(0.30005, -0.10, 1000.0), _state(0.30, -0.10005, 1000.0)]
    view = still_view("v1", states, jpeg.tobytes(), cloud, pan_offset=0.1, tilt_offset=-0.2, timings={"total": 1.5})
    assert (view.pan, view.tilt, view.zoom) == (pytest.approx(0.2), pytest.approx(0.1), 1000.0)
    assert (view.image_width, view.image_height) == (W, H)
    assert view.state_spread == pytest.approx(5e-5)
    assert view.timings == {"total": 1.5}
    with pytest.raises(CaptureError, match="moved"):
        still_view("v", [*states, _state(0.3, -0.1, moving=True)], jpeg.tobytes(), cloud)
    with pytest.raises(CaptureError, match="changed by"):
        still_view("v", [_state(0.3, -0.1), _state(0.301, -0.1)], jpeg.tobytes(), cloud)
    with pytest.raises(CaptureError, match="not a decodable JPEG"):
        still_view("v", states, b"not a jpeg", cloud)
    with pytest.raises(CaptureError, match="no ptz/state"):
        still_view("v", [], jpeg.tobytes(), cloud)


def test_a_cloud_goes_into_base_link_only_from_the_frame_its_pose_is_for():
    T = Transform.from_xyz_rpy(0.25, 0.0, 0.4, 0, 0, math.pi / 2)
    pts = np.array([[1.0, 0.0, 0.0, 0.7]])
    frames = {"base_frame": "base_link", "laser_frame": "velodyne", "T_base_laser": T}
    np.testing.assert_allclose(cloud_in_base(pts, "/velodyne", **frames), [[0.25, 1.0, 0.4, 0.7]], atol=1e-12)
    assert cloud_in_base(pts, "base_link", **frames) is pts
    with pytest.raises(CaptureError, match="frame 'laser_link'"):
        cloud_in_base(pts, "laser_link", **frames)


def test_picking_and_capture_modules_import_without_ros():
    import subprocess
    import sys

    code = (
        "import sys\n"
        "import axis_ptz_ros2.calibration.picking, axis_ptz_ros2.calibration.capture, axis_ptz_ros2.calibration.cli\n"
        "bad = [m for m in sys.modules if m.split('.')[0] in ('rclpy', 'sensor_msgs', 'axis_ptz_interfaces')]\n"
        "assert not bad, bad\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True, timeout=60)
