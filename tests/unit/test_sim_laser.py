"""The simulated laser scanner's maths without ROS (axis_ptz_ros2.sim.laser): ray grid, returns, noise."""

from __future__ import annotations

import math

import numpy as np
import pytest

from axis_ptz_ros2.sim.laser import StaticScan, scan_directions, trace_scan
from axis_ptz_ros2.sim.scene import shared_scene
from axis_ptz_ros2.sim.world import load_world
from axis_ptz_ros2.transforms import Transform

pytestmark = pytest.mark.unit


class GroundOnly:
    """A scene of nothing but the ground plane z = 0, grey level ``grey`` (BGR), ray ids 0."""

    def __init__(self, bgr=(100, 150, 200)):
        self.bgr = np.asarray(bgr, np.uint8)

    def raycast(self, origin, dirs):
        dirs = np.asarray(dirs, np.float64)
        with np.errstate(divide="ignore"):
            depth = np.where(dirs[:, 2] < 0, -origin[2] / dirs[:, 2], np.inf)
        bgr = np.broadcast_to(self.bgr, (dirs.shape[0], 3)).copy()
        return bgr, depth, np.zeros(dirs.shape[0], np.int64)


def test_scan_directions_are_unit_rings_elevation_major_from_minus_pi():
    d = scan_directions(-math.radians(10), math.radians(10), math.radians(5), math.radians(90))
    assert d.shape == (5 * 4, 3)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0)
    el = np.degrees(np.arcsin(d[:, 2])).reshape(5, 4)
    np.testing.assert_allclose(el, np.repeat([[-10.0], [-5.0], [0.0], [5.0], [10.0]], 4, axis=1), atol=1e-9)
    az = np.degrees(np.arctan2(d[:, 1], d[:, 0])).reshape(5, 4)[0]
    np.testing.assert_allclose(az, [-180.0, -90.0, 0.0, 90.0], atol=1e-9)


def test_scan_directions_keep_the_top_ring_despite_rounding_and_a_full_turn():
    # 60 deg / 0.5 deg is 120 steps in exact arithmetic; the top ring must not be lost to 119.99999
    d = scan_directions(-math.radians(30), math.radians(30), math.radians(0.5), math.radians(0.5))
    assert d.shape == (121 * 720, 3)
    assert math.degrees(math.asin(d[-1, 2])) == pytest.approx(30.0)
    # azimuth spacing rounds to a whole turn: 7 deg asks for 51.4 rays, 51 are spread evenly
    ring = scan_directions(0.0, 0.0, 0.1, math.radians(7))
    assert ring.shape == (51, 3)
    assert np.degrees(np.diff(np.arctan2(ring[:, 1], ring[:, 0]))) == pytest.approx(np.full(50, 360 / 51))


def test_trace_keeps_returns_inside_the_range_limits_with_luminance_intensity():
    h = 1.0
    T = Transform(np.eye(3), np.array([0.0, 0.0, h]))
    dirs = scan_directions(-math.radians(60), math.radians(10), math.radians(10), math.radians(90))
    kept, ranges, lum = trace_scan(GroundOnly(), T, dirs, 1.5, 5.0)
    el = np.arcsin(dirs[:, 2])
    expect = (el < 0) & (h / np.sin(np.maximum(-el, 1e-12)) >= 1.5) & (h / np.sin(np.maximum(-el, 1e-12)) <= 5.0)
    assert kept.shape[0] == int(expect.sum()) > 0
    np.testing.assert_allclose(kept, dirs[expect])
    np.testing.assert_allclose(ranges, h / -kept[:, 2])
    np.testing.assert_allclose(lum, (0.114 * 100 + 0.587 * 150 + 0.299 * 200) / 255.0)


def test_trace_uses_the_scanner_pose():
    # a scanner pitched down by 90 deg about y: its +x ray points at the ground straight below
    pitch = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
    T = Transform(pitch, np.array([3.0, 0.0, 2.0]))
    kept, ranges, _ = trace_scan(GroundOnly(), T, np.array([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]]), 0.1, 10.0)
    np.testing.assert_allclose(kept, [[1.0, 0.0, 0.0]])
    assert ranges.tolist() == pytest.approx([2.0])


def test_scans_are_exact_without_noise_and_clipped_gaussian_with_it():
    T = Transform(np.eye(3), np.array([0.0, 0.0, 1.0]))
    dirs = scan_directions(-math.radians(50), -math.radians(10), math.radians(0.5), math.radians(1))
    scan = StaticScan.trace(GroundOnly(), T, dirs, 1.0, 5.0, seed=3)
    exact = scan.points()
    np.testing.assert_allclose(np.linalg.norm(exact, axis=1), scan.ranges)
    np.testing.assert_array_equal(scan.points(0.0), exact)
    a, b = scan.points(0.05), scan.points(0.05)
    ra, rb = np.linalg.norm(a, axis=1), np.linalg.norm(b, axis=1)
    assert ra.min() >= 1.0 - 1e-12
    assert ra.max() <= 5.0 + 1e-12
    # directions exact, a new draw per scan: var(ra - rb) = 2 sigma^2 away from the clipping
    np.testing.assert_allclose(a / ra[:, None], scan.directions, atol=1e-12)
    mid = (scan.ranges > 1.3) & (scan.ranges < 4.7)
    assert float(np.std((ra - rb)[mid])) / math.sqrt(2) == pytest.approx(0.05, rel=0.1)
    # the same seed gives the same scans
    again = StaticScan.trace(GroundOnly(), T, dirs, 1.0, 5.0, seed=3)
    np.testing.assert_array_equal(again.points(0.05), a)
    # noise from a generator the caller gives: a fresh one of the same seed gives the same noise in every scan,
    # and leaves the scan source's own stream where it was
    fixed = scan.points(0.05, np.random.default_rng(11))
    np.testing.assert_array_equal(scan.points(0.05, np.random.default_rng(11)), fixed)
    assert not np.array_equal(fixed, a)
    np.testing.assert_array_equal(again.points(0.05), b)
    np.testing.assert_array_equal(scan.points(0.05), again.points(0.05))  # both at their third draw


def test_the_simulated_scene_returns_ground_at_its_true_range():
    world = load_world()
    dirs = scan_directions(-math.radians(30), -math.radians(20), math.radians(5), math.radians(45))
    kept, ranges, lum = trace_scan(shared_scene(world), world.T_base_laser, dirs, 0.3, 30.0)
    assert kept.shape[0] > 0
    assert np.all((lum >= 0) & (lum <= 1))
    P = world.T_base_laser.apply(kept * ranges[:, None])
    on_ground = np.abs(P[:, 2]) < 2e-3
    assert on_ground.sum() >= kept.shape[0] // 2  # most of these downward rays hit the ground, not a target
