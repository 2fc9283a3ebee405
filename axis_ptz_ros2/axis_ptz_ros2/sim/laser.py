"""The simulated 3-D laser scanner's maths (ROS-free): its ray grid, its returns from the scene, one scan's points.

Rays lie on a regular elevation × azimuth grid in the scanner frame and are traced from the scanner's true pose
through :meth:`~axis_ptz_ros2.sim.scene.Scene.raycast` (targets, ground, skyline); returns within
``[min_range, max_range]`` are kept, with intensity = luminance of the hit surface (0…1). The scene is static, so
the geometry is traced once (:meth:`StaticScan.trace`); each scan (:meth:`StaticScan.points`) draws its own
Gaussian range noise, like a real scanner looking at a static scene, or takes it from a generator the caller
gives (a fresh ``default_rng(seed)`` each time: the same noise in every scan). The ``axis_laser_sim`` node publishes the
scans (``nodes/laser_sim.py``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from axis_ptz_ros2.sim.scene import Scene
from axis_ptz_ros2.transforms import FloatArray, Transform

#: BGR weights of the luminance a return's intensity is (ITU-R BT.601, as OpenCV's grey conversion).
_LUMA_BGR = np.array([0.114, 0.587, 0.299])


def scan_directions(min_el: float, max_el: float, el_step: float, az_step: float) -> FloatArray:
    """Unit ray directions (N, 3) in the scanner frame, elevation-major (rings), azimuth −π…π."""
    n_el = int(math.floor((max_el - min_el) / el_step + 1e-9)) + 1
    el = min_el + el_step * np.arange(n_el)
    n_az = max(1, int(round(2 * math.pi / az_step)))
    az = -math.pi + (2 * math.pi / n_az) * np.arange(n_az)
    E, A = np.meshgrid(el, az, indexing="ij")
    d = np.stack([np.cos(E) * np.cos(A), np.cos(E) * np.sin(A), np.sin(E)], -1)
    return np.asarray(d.reshape(-1, 3), dtype=np.float64)


def trace_scan(
    scene: Scene, T_base_laser: Transform, dirs_laser: FloatArray, min_range: float, max_range: float
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Exact returns: (unit directions in the laser frame (M, 3), ranges (M,), intensities (M,))."""
    d_base = dirs_laser @ T_base_laser.R.T
    bgr, depth, _ = scene.raycast(T_base_laser.t, d_base)
    ok = np.isfinite(depth) & (depth >= min_range) & (depth <= max_range)
    lum = bgr[ok].astype(np.float64) @ _LUMA_BGR / 255.0
    return dirs_laser[ok], depth[ok], lum


@dataclass(frozen=True)
class StaticScan:
    """The exact returns of a scanner looking at a static scene (traced once) and its range-noise source."""

    directions: FloatArray  #: (M, 3) unit directions of the returns in the scanner frame
    ranges: FloatArray  #: (M,) exact ranges, metres
    intensity: FloatArray  #: (M,) luminance of the hit surfaces, 0…1
    min_range: float
    max_range: float
    rng: np.random.Generator

    @classmethod
    def trace(
        cls,
        scene: Scene,
        T_base_laser: Transform,
        dirs_laser: FloatArray,
        min_range: float,
        max_range: float,
        seed: int = 0,
    ) -> StaticScan:
        """Trace ``dirs_laser`` from the scanner's pose once (:func:`trace_scan`); ``seed`` seeds the noise."""
        dirs, ranges, intensity = trace_scan(scene, T_base_laser, dirs_laser, min_range, max_range)
        return cls(dirs, ranges, intensity, float(min_range), float(max_range), np.random.default_rng(seed))

    def points(self, range_noise: float = 0.0, rng: np.random.Generator | None = None) -> FloatArray:
        """One scan: the returns as (M, 3) points in the scanner frame, each range with Gaussian noise of standard
        deviation ``range_noise`` (m; 0 = exact) drawn from ``rng`` (default: this scan source's own stream, so
        fresh noise at every call), clipped into ``[min_range, max_range]``."""
        r = self.ranges
        if range_noise > 0.0:
            gen = self.rng if rng is None else rng
            r = np.clip(r + gen.normal(0.0, range_noise, r.shape), self.min_range, self.max_range)
        return np.asarray(self.directions * r[:, None], dtype=np.float64)
