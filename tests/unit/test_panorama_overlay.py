"""The visualizer's picture without ROS (axis_ptz_ros2.panorama_overlay): pose, intrinsics, depth, drawing."""

from __future__ import annotations

import math
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from axis_ptz_ros2.config import MountConfig, load_camera_model, load_mount, load_robot
from axis_ptz_ros2.panorama_overlay import (
    OverlaySettings,
    PanoramaOverlay,
    footprint_polylines,
    intrinsics_from_state,
)
from axis_ptz_ros2.transforms import Transform, rot_z
from tests.support.panorama_expect import PANO, H, W, expected_pixel  # noqa: E402

pytestmark = pytest.mark.unit

HFOV = math.radians(47.98)


def _state(pan: float = 0.0, tilt: float = 0.0, zoom: float = 1.0, hfov: float = HFOV, vfov: float | None = None):
    if vfov is None:
        vfov = 2 * math.atan(math.tan(hfov / 2) * (576 / 704) * (4 / 3))
    return SimpleNamespace(pan=pan, tilt=tilt, zoom=zoom, hfov=hfov, vfov=vfov)


class Clock:
    def __init__(self) -> None:
        self.t = 50.0

    def __call__(self) -> float:
        return self.t


def _overlay(mount: MountConfig | None = None) -> tuple[PanoramaOverlay, Clock]:
    clock = Clock()
    return PanoramaOverlay(load_camera_model(), mount or load_mount(), load_robot(), clock=clock), clock


def _mask(img, colour):
    b, g, r = (img[..., i].astype(int) for i in range(3))
    if colour == "red":
        return (r > 170) & (g < 90) & (b < 90)
    return (r > 170) & (g > 170) & (b < 90)  # yellow


GREY = np.full((H, W, 3), 128, np.uint8)


def test_footprint_polylines_unwrap_and_pole():
    # A box straddling the seam.
    pts = np.array([[1000.0, 100.0], [20.0, 100.0], [20.0, 200.0], [1000.0, 200.0]])
    lines, closed = footprint_polylines(pts, 1024)
    assert closed
    mid = lines[1]
    assert np.allclose(mid[:, 0], [1000.0, 1044.0, 1044.0, 1000.0])
    assert np.allclose(lines[0][:, 0], mid[:, 0] - 1024)
    assert np.allclose(lines[2][:, 0], mid[:, 0] + 1024)
    # A ring around the zenith (camera looking straight up): open band spanning the full width.
    xs = np.linspace(0, 1024, 16, endpoint=False)
    ring = np.stack([xs, np.full_like(xs, 30.0)], -1)
    lines, closed = footprint_polylines(ring, 1024)
    assert not closed
    assert lines[1][-1, 0] - lines[1][0, 0] == pytest.approx(1024.0)


def test_intrinsics_from_the_state_fov_else_the_zoom_model():
    intr = intrinsics_from_state(_state(vfov=math.radians(30.0)), 704, 576)
    assert intr is not None
    assert intr.fx == pytest.approx(352 / math.tan(HFOV / 2))
    assert intr.fy == pytest.approx(288 / math.tan(math.radians(15.0)))
    assert (intr.cx, intr.cy) == (351.5, 287.5)
    no_vfov = intrinsics_from_state(_state(vfov=math.nan), 704, 576)
    assert no_vfov is not None
    assert no_vfov.fy == no_vfov.fx  # square pixels without a vfov
    assert intrinsics_from_state(_state(hfov=0.0, vfov=0.5), 704, 576) is None
    assert intrinsics_from_state(_state(hfov=math.inf, vfov=0.5), 704, 576) is None

    ov, _ = _overlay()
    zoom = ov.model.zoom
    widest = ov.intrinsics(704, 576)  # no state yet: the widest zoom
    assert widest.hfov == pytest.approx(zoom.intrinsics(zoom.min_zoom, 704, 576).hfov)
    ov.ptz_state(_state(zoom=5000.0, hfov=math.nan))  # no fov in the state: the zoom model at its zoom
    assert ov.intrinsics(704, 576).fx == pytest.approx(zoom.intrinsics(5000.0, 704, 576).fx)
    assert ov.intrinsics(704, 576).fx > widest.fx
    ov.ptz_state(_state(zoom=5000.0))  # the state's own fov wins
    assert ov.intrinsics(704, 576).hfov == pytest.approx(HFOV)


def test_a_fresh_ptz_transform_wins_over_mount_and_kinematics():
    ov, clock = _overlay()
    assert ov.optical_pose(2.0) is None  # nothing heard yet
    ov.ptz_state(_state(0.6, 0.2))
    from_state = ov.optical_pose(2.0)
    assert from_state is not None
    expected = ov.mount.transform @ ov.model.head.optical_in_ptz_base(0.6, 0.2)
    np.testing.assert_allclose(from_state.matrix(), expected.matrix())
    T = Transform(rot_z(1.0), np.array([1.0, 2.0, 3.0]))
    ov.ptz_transform(T)
    clock.t += 2.0
    assert ov.optical_pose(2.0) is T  # exactly the timeout old: still fresh
    clock.t += 0.01
    np.testing.assert_allclose(ov.optical_pose(2.0).matrix(), expected.matrix())  # stale: back to the state
    assert ov.optical_pose(10.0) is T


def test_mount_offsets_are_not_added_to_the_joint_state():
    """ptz/state is in joint coordinates: a mount with encoder offsets draws where the nominal mount does."""
    nominal, _ = _overlay()
    offset = replace(load_mount(), pan_offset=0.35, tilt_offset=-0.12)
    shifted, _ = _overlay(offset)
    for ov in (nominal, shifted):
        ov.ptz_state(_state(0.6, 0.2))
    np.testing.assert_allclose(shifted.optical_pose(2.0).matrix(), nominal.optical_pose(2.0).matrix())


def test_depth_fixed_or_laser_then_ground_then_fixed():
    ov, _ = _overlay()
    ov.ptz_state(_state(0.4, -0.3))
    T = ov.optical_pose(2.0)
    assert ov.depth(T, 50.0, auto_depth=False) == 50.0
    ground = ov.depth(T, 50.0, auto_depth=True)  # no laser: the ground along the axis
    axis = T.R[:, 2]
    assert ground == pytest.approx((ov.robot.ground_z - T.t[2]) / axis[2])
    # a laser point on the axis 2 m out (given in the laser frame) is nearer than the ground
    target_base = T.t + 2.0 * axis
    ov.laser_cloud(ov.T_base_laser.inverse().apply(target_base[None, :]))
    assert ov.depth(T, 50.0, auto_depth=True) == pytest.approx(2.0)
    # the laser's pose heard on laser/transform moves the cloud with it
    ov.laser_pose(Transform(np.eye(3), ov.T_base_laser.t + [0.0, 0.0, 5.0]))
    assert ov.depth(T, 50.0, auto_depth=True) == pytest.approx(ground)
    up = _overlay()[0]
    up.ptz_state(_state(0.0, 0.3))  # looking up, no laser: the fixed depth
    assert up.depth(up.optical_pose(2.0), 7.0, auto_depth=True) == 7.0


@pytest.mark.parametrize(("pan", "tilt", "depth"), [(0.6, 0.2, 5.0), (-1.2, -0.3, 5.0), (0.6, 0.2, 1.0)])
def test_the_red_mark_lands_on_the_look_point_seen_from_the_panorama(pan, tilt, depth):
    ov, _ = _overlay()
    ov.ptz_state(_state(pan, tilt))
    img = ov.draw(GREY, OverlaySettings(depth=depth))
    assert np.array_equal(GREY, np.full((H, W, 3), 128, np.uint8))  # the input is not drawn on
    ys, xs = np.nonzero(_mask(img, "red"))
    assert xs.size > 20
    ex, ey = expected_pixel(pan, tilt, depth)
    assert abs(xs.mean() - ex) < 1.5, (xs.mean(), ex)
    assert abs(ys.mean() - ey) < 1.5, (ys.mean(), ey)
    assert ov.last_look_pixel == pytest.approx((ex, ey), abs=0.05)
    if depth == 1.0:  # the naive thesis mapping (pan/tilt as panorama az/el) would put it elsewhere at 1 m
        assert abs(xs.mean() - ((0.5 - pan / (2 * math.pi)) * W - 0.5)) > 10
    # The yellow footprint surrounds the mark: about one HFOV (48 deg ~ 136 px at W=1024) wide.
    fy, fx = np.nonzero(_mask(img, "yellow"))
    assert fx.size > 50
    assert fx.min() < ex - 40 < ex + 40 < fx.max()
    assert fy.min() < ey < fy.max()


def test_marker_radius_and_nothing_drawn_without_a_pose():
    ov, _ = _overlay()
    assert np.array_equal(ov.draw(GREY, OverlaySettings()), GREY)
    assert ov.last_look_pixel is None
    ov.ptz_state(_state(0.6, 0.2))
    small = _mask(ov.draw(GREY, OverlaySettings(depth=5.0)), "red").sum()  # 0 = max(4, W/200) = 5 px
    big = _mask(ov.draw(GREY, OverlaySettings(depth=5.0, marker_radius=20)), "red").sum()
    assert big > 10 * small > 0


def test_the_footprint_wraps_at_the_seam_and_the_panorama_pose_is_used():
    ov, _ = _overlay()
    # An optical frame looking straight back (-x of base_link) from 1 m above base_link: the look point is at
    # the seam (azimuth pi), so the mark and the footprint appear at both image edges.
    R_back = rot_z(math.pi) @ np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    ov.ptz_state(_state(0.0, 0.0))  # contradicts the transform: the transform must win
    ov.ptz_transform(Transform(R_back, np.array([0.216, -0.044, 1.0])))
    img = ov.draw(GREY, OverlaySettings(depth=10.0))
    ys, xs = np.nonzero(_mask(img, "red"))
    assert xs.min() < 8
    assert xs.max() > W - 9  # split circle at both edges
    assert np.all((xs < 20) | (xs > W - 21))
    el = math.atan2(1.0 - 0.75, 10.0)
    assert abs(ys.mean() - ((0.5 - el / math.pi) * H - 0.5)) < 1.5
    fy, fx = np.nonzero(_mask(img, "yellow"))
    assert np.any(fx < 30)
    assert np.any(fx > W - 31)
    assert not np.any((fx > 200) & (fx < W - 200))  # no line drawn across the whole panorama

    # A panorama yawed by +90 deg (heard on panorama/transform): azimuths shift by -90 deg.
    yawed, _ = _overlay()
    yawed.panorama_pose(Transform(rot_z(math.pi / 2), PANO.copy()))
    yawed.ptz_state(_state(0.0, 0.0))
    xs = np.nonzero(_mask(yawed.draw(GREY, OverlaySettings(depth=5.0)), "red"))[1]
    assert abs(xs.mean() - (expected_pixel(0.0, 0.0, 5.0)[0] + W / 4)) < 1.5
