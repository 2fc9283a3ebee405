"""Where the PTZ's look point must land on the panorama, computed independently of the package's code path
(shared by the visualizer's ROS test and the overlay's unit test)."""

from __future__ import annotations

import math

import numpy as np

W, H = 1024, 512
# Nominal configuration (config/mount.yaml, config/robot.yaml, config/axis214.yaml), written out here so the
# expected pixel is computed independently of the module's code path.
PTZ_BASE = np.array([-0.214, -0.044, 0.455])
H_TILT = 0.0687
D_OPT = 0.03  # optical centre ahead of the tilt axis (config/axis214.yaml head.d_opt)
PANO = np.array([0.216, -0.044, 0.75])


def expected_pixel(pan: float, tilt: float, depth: float, pano: np.ndarray = PANO) -> tuple[float, float]:
    """Panorama pixel (x, y) of the point ``depth`` m along the optical axis at joint angles ``pan``, ``tilt``."""
    ray = np.array([math.cos(tilt) * math.cos(pan), math.cos(tilt) * math.sin(pan), math.sin(tilt)])
    c = PTZ_BASE + [0.0, 0.0, H_TILT] + D_OPT * ray
    d = c + depth * ray - pano
    az = math.atan2(d[1], d[0])
    el = math.atan2(d[2], math.hypot(d[0], d[1]))
    return (0.5 - az / (2 * math.pi)) * W - 0.5, (0.5 - el / math.pi) * H - 0.5
