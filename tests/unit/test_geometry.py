"""The single unit/sign convention and the optics (geometry.py)."""

import math

import numpy as np
import pytest

from axis_ptz_ros2 import geometry as g
from axis_ptz_ros2 import optics, transforms
from tests.support.models import AXIS_214_ZOOM

pytestmark = pytest.mark.unit


def test_upright_cw_convention_is_axis_documented_sign():
    conv = g.VapixConvention()
    # VAPIX +10° pan = camera's right = clockwise from above = negative REP-103 yaw.
    pan, tilt = conv.to_ros(10.0, 20.0)
    assert pan == pytest.approx(-math.radians(10.0))
    assert tilt == pytest.approx(math.radians(20.0))
    assert conv.to_vapix(pan, tilt) == pytest.approx((10.0, 20.0))
    assert conv.pan_rate_to_vapix(0.5) == pytest.approx(-0.5)


@pytest.mark.parametrize("direction", list(g.PanDirection))
@pytest.mark.parametrize("mount", list(g.Mount))
def test_round_trip_every_configuration(direction, mount):
    conv = g.VapixConvention(direction, mount)
    for pan_deg, tilt_deg in [(0.0, 0.0), (123.4567, -29.9), (-170.0, 90.0), (0.0001, 0.0003)]:
        assert conv.to_vapix(*conv.to_ros(pan_deg, tilt_deg)) == pytest.approx((pan_deg, tilt_deg), abs=1e-12)


def test_ceiling_mount_mirrors_both_axes():
    up, ceil = g.VapixConvention(), g.VapixConvention(mount=g.Mount.CEILING)
    assert ceil.to_ros(10, 20) == pytest.approx(tuple(-x for x in up.to_ros(10, 20)))
    assert ceil.limits_to_ros(-170, 170, -30, 90) == pytest.approx(
        (-math.radians(170), math.radians(170), -math.radians(90), math.radians(30))
    )


def test_zoom_model_matches_axis_214_lens_calculator():
    z = AXIS_214_ZOOM
    assert z.intrinsics(1, 704, 576).fx == pytest.approx(791, abs=1.0)
    assert z.intrinsics(9999, 704, 576).fx == pytest.approx(14937, rel=2e-3)
    assert math.degrees(z.hfov(9999)) == pytest.approx(2.70, abs=0.01)
    assert math.degrees(z.hfov(5000)) == pytest.approx(5.13, abs=0.01)  # table in vapix.md §8.3
    k = z.intrinsics(1, 704, 576)
    assert k.fy / k.fx == pytest.approx(12 / 11)  # PAL pixel aspect
    assert math.degrees(k.vfov) == pytest.approx(36.91, abs=0.02)
    assert (k.cx, k.cy) == (351.5, 287.5)
    for zoom in (1, 1234.5, 5000, 9999):
        assert z.zoom_for_magnification(z.magnification(zoom)) == pytest.approx(zoom)
        assert z.zoom_for_hfov(z.hfov(zoom)) == pytest.approx(zoom)


def test_zoom_table_interpolates_monotonically_in_log_magnification():
    m = optics.ZoomModel(47.98, 18.88, table=((1, 1.0), (3868, 2.0), (7736, 3.0), (9999, 3.584961)))
    assert m.magnification(3868) == pytest.approx(2.0)
    assert m.magnification(2000) == pytest.approx(math.exp(math.log(2.0) * 1999 / 3867))
    assert m.zoom_for_magnification(3.0) == pytest.approx(7736)
    with pytest.raises(ValueError, match="monotone"):
        optics.ZoomModel(47.98, 18.88, table=((1, 2.0), (10, 1.0)))


def test_kinematics_optical_axis_and_frames():
    kin = g.PtzKinematics(h_tilt=0.07, d_opt=(0.05, 0.0, 0.0))
    T = kin.optical_in_ptz_base(0.0, 0.0)
    # optical z (forward) = body +x, optical x (right) = body −y, optical y (down) = body −z
    assert T.R[:, 2] == pytest.approx([1, 0, 0])
    assert T.R[:, 0] == pytest.approx([0, -1, 0])
    assert T.R[:, 1] == pytest.approx([0, 0, -1])
    assert T.t == pytest.approx([0.05, 0, 0.07])
    T = kin.optical_in_ptz_base(math.radians(90), math.radians(30))
    fwd = T.R[:, 2]
    assert g.direction_to_pan_tilt(fwd) == pytest.approx((math.radians(90), math.radians(30)))


@pytest.mark.parametrize("d_opt", [(0.0, 0.0, 0.0), (0.05, 0.0, 0.0), (0.03, 0.02, -0.015)])
def test_look_at_puts_point_on_optical_axis(d_opt):
    kin = g.PtzKinematics(h_tilt=0.0687, d_opt=d_opt)
    for P in ([3.0, 0.0, 0.5], [0.2, 3.0, -0.4], [-2.0, -1.0, 1.5], [0.6, 0.3, 0.1]):
        pan, tilt = kin.look_at(P)
        T = kin.optical_in_ptz_base(pan, tilt)
        p_opt = T.inverse().apply(P)
        assert p_opt[2] > 0
        assert math.hypot(p_opt[0], p_opt[1]) / p_opt[2] < 1e-9


@pytest.mark.parametrize("tilt_deg", [-40.0, 0.0, 40.0, 80.0])
def test_center_on_pixel_is_exact_at_any_tilt(tilt_deg):
    intr = AXIS_214_ZOOM.intrinsics(1, 704, 576)
    kin = g.PtzKinematics(h_tilt=0.0, d_opt=(0.0, 0.0, 0.0))
    pan, tilt = math.radians(20.0), math.radians(tilt_deg)
    u, v = 600.0, 100.0
    # a far point seen at pixel (u, v)
    ray_opt = intr.ray(u, v)
    P = kin.optical_in_ptz_base(pan, tilt).apply(ray_opt * 1000.0)
    new_pan, new_tilt = g.center_on_pixel(pan, tilt, u, v, intr)
    p = kin.optical_in_ptz_base(new_pan, new_tilt).inverse().apply(P)
    px = intr.project(p)[0]
    assert px == pytest.approx([intr.cx, intr.cy], abs=1e-6)
    naive_pan = pan - math.atan((u - intr.cx) / intr.fx)  # the wrong formula differs when tilt != 0
    if abs(tilt_deg) >= 40:
        assert abs(naive_pan - new_pan) > math.radians(1.0)


def test_equirect_round_trip_and_anchor_pixels():
    W, H = 2000, 1000
    xs, ys = np.meshgrid(np.arange(0, W, 37.3), np.arange(0, H, 29.1))
    d = g.equirect_to_direction(xs, ys, W, H)
    back = g.direction_to_equirect(d, W, H)
    assert back[..., 0] == pytest.approx(xs, abs=1e-6)
    assert back[..., 1] == pytest.approx(ys, abs=1e-6)
    # straight ahead (az 0, el 0) is the image centre; left (+y, az +90°) is at a quarter width
    assert g.direction_to_equirect([1, 0, 0], W, H) == pytest.approx([W / 2 - 0.5, H / 2 - 0.5])
    assert g.direction_to_equirect([0, 1, 0], W, H) == pytest.approx([W / 4 - 0.5, H / 2 - 0.5])


def test_transform_algebra_and_quaternions():
    T = transforms.Transform.from_xyz_rpy(-0.214, -0.044, 0.455, 0.1, -0.2, 0.3)
    assert (T @ T.inverse()).matrix() == pytest.approx(np.eye(4), abs=1e-12)
    assert T.xyz_rpy() == pytest.approx((-0.214, -0.044, 0.455, 0.1, -0.2, 0.3))
    q = transforms.matrix_to_quaternion(T.R)
    assert transforms.quaternion_to_matrix(*q) == pytest.approx(T.R, abs=1e-12)
    assert transforms.matrix_to_quaternion(transforms.rot_z(math.pi)) == pytest.approx((0, 0, 1, 0), abs=1e-12)


def _same_pose(p: transforms.Pose, T: transforms.Transform) -> None:
    assert p.q[3] >= 0.0
    assert math.isclose(sum(v * v for v in p.q), 1.0, abs_tol=1e-12)
    np.testing.assert_allclose(p.t, T.t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(transforms.quaternion_to_matrix(*p.q), T.R, rtol=0, atol=1e-12)
    if T.R.trace() > -0.99:  # away from w = 0 the quaternion itself is unique (w >= 0)
        np.testing.assert_allclose(p.q, transforms.matrix_to_quaternion(T.R), rtol=0, atol=1e-12)


@pytest.mark.parametrize("d_opt", [(0.0, 0.0, 0.0), (0.05, 0.0, 0.0), (0.031, -0.012, 0.027)])
def test_optical_pose_in_floats_equals_the_numpy_transform(d_opt):
    k = g.PtzKinematics(h_tilt=0.0687, d_opt=d_opt)
    rng = np.random.default_rng(7)
    angles = [(0.0, 0.0), (math.pi, 0.0), (-math.pi, math.pi / 2), (2.9, -math.pi / 2), (1e-9, -1e-9)]
    angles += [(float(p), float(t)) for p, t in zip(rng.uniform(-4, 4, 300), rng.uniform(-1.6, 1.6, 300), strict=True)]
    for pan, tilt in angles:
        _same_pose(k.optical_pose(pan, tilt), k.optical_in_ptz_base(pan, tilt))


def test_pose_composition_equals_the_numpy_transform():
    rng = np.random.default_rng(11)
    for _ in range(200):
        a = transforms.Transform.from_xyz_rpy(*rng.uniform(-2, 2, 3), *rng.uniform(-math.pi, math.pi, 3))
        b = transforms.Transform.from_xyz_rpy(*rng.uniform(-2, 2, 3), *rng.uniform(-math.pi, math.pi, 3))
        pa, pb = transforms.Pose.from_transform(a), transforms.Pose.from_transform(b)
        _same_pose(pa, a)
        _same_pose(pa @ pb, a @ b)
        np.testing.assert_allclose(pa.transform().matrix(), a.matrix(), rtol=0, atol=1e-12)
    v = (0.3, -1.2, 2.5)
    q = transforms.Pose.from_transform(transforms.Transform(transforms.rot_z(0.7) @ transforms.rot_x(-0.4))).q
    np.testing.assert_allclose(
        transforms.quaternion_rotate(q, v), transforms.rot_z(0.7) @ transforms.rot_x(-0.4) @ np.array(v), atol=1e-12
    )
