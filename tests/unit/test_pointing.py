"""Panorama click → 3-D point → PTZ look-at, with parallax (pointing.py), and the robot config."""

import math

import numpy as np
import pytest

from axis_ptz_ros2 import pointing as pt
from axis_ptz_ros2.config import load_robot
from axis_ptz_ros2.geometry import PtzKinematics, direction_to_equirect
from axis_ptz_ros2.transforms import Transform
from tests.support.models import AXIS_214_ZOOM

pytestmark = pytest.mark.unit

W, H = 2048, 1024
T_PANO = Transform.from_xyz_rpy(0.216, -0.044, 0.75, 0, 0, 0)
T_PTZ = Transform.from_xyz_rpy(-0.214, -0.044, 0.455, 0, 0, 0)
KIN = PtzKinematics(h_tilt=0.0687)


def _click_of(point_base):
    d = T_PANO.inverse().apply(point_base)
    return direction_to_equirect(d, W, H)


def _ptz_error_deg(target, pan, tilt):
    p_ptz = T_PTZ.inverse().apply(target)
    want = KIN.look_at(p_ptz)
    return math.degrees(math.hypot(want[0] - pan, want[1] - tilt))


def test_side_target_parallax_is_large_without_depth_and_removed_with_laser_depth():
    target = np.array([-0.214 + 0.0, 3.0, 0.52])  # 3 m to the side of the PTZ at about camera height
    x, y = _click_of(target)
    o, d = pt.panorama_ray(x, y, W, H, T_PANO)
    # naive (thesis): PTZ pan/tilt = panorama azimuth/elevation
    naive_pan, naive_tilt = math.atan2(d[1], d[0]), math.atan2(d[2], math.hypot(d[0], d[1]))
    assert _ptz_error_deg(target, naive_pan, naive_tilt) > 7.0  # ≈ 8° (geometry ref §4)
    # with a laser cloud around the target the corrected point is within the laser noise
    rng = np.random.default_rng(1)
    cloud = target + rng.normal(0, 0.01, (200, 3))
    cloud = np.vstack([cloud, rng.uniform(-20, 20, (2000, 3))])
    hit = pt.point_along_ray(o, d, cloud, cone_deg=1.0)
    assert hit.source is pt.DepthSource.LASER
    pan, tilt = KIN.look_at(T_PTZ.inverse().apply(hit.point_base))
    assert _ptz_error_deg(target, pan, tilt) < 0.15


def test_straight_ahead_error_is_small_and_ground_fallback_works():
    target = np.array([3.2, -0.044, 0.0])  # on the ground ahead
    x, y = _click_of(target)
    o, d = pt.panorama_ray(x, y, W, H, T_PANO)
    hit = pt.point_along_ray(o, d, None, ground_z=0.0)
    assert hit.source is pt.DepthSource.GROUND
    assert hit.point_base == pytest.approx(target, abs=0.02)
    up = pt.point_along_ray(o, np.array([1.0, 0, 0.2]) / math.hypot(1, 0.2), None, default_range=7.0)
    assert up.source is pt.DepthSource.DEFAULT
    assert up.range_m == 7.0


def test_footprint_centre_projects_where_the_ptz_looks():
    pan, tilt = math.radians(30), math.radians(-5)
    T_opt = T_PTZ @ KIN.optical_in_ptz_base(pan, tilt)
    intr = AXIS_214_ZOOM.intrinsics(1, 704, 576)
    poly = pt.footprint_on_panorama(intr, T_opt, T_PANO, W, H, depth_m=10.0)
    assert poly.shape == (32, 2)
    centre_pt = T_opt.t + 10.0 * T_opt.R[:, 2]
    c = pt.project_to_panorama(centre_pt, T_PANO, W, H)[0]
    lo, hi = poly.min(axis=0), poly.max(axis=0)
    assert lo[0] < c[0] < hi[0]
    assert lo[1] < c[1] < hi[1]
    # the footprint is about one HFOV wide on the panorama at zoom 1 (48° of 360°)
    assert (hi[0] - lo[0]) / W * 360 == pytest.approx(48, abs=6)


def test_robot_config_loads():
    r = load_robot()
    assert r.panorama.frame == "panorama_link"
    assert r.panorama.pose.t == pytest.approx([0.216, -0.044, 0.75])
