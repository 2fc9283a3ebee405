"""The one place where units, signs and frames are defined (ROS-free, numpy only): the VAPIX ↔ REP-103 conversion,
the kinematics of the pan/tilt head, pointing at pixels and directions, the equirectangular panorama.

Rotations and rigid transforms (matrices, quaternions, :class:`~axis_ptz_ros2.transforms.Pose`) are in
:mod:`axis_ptz_ros2.transforms`, the zoom optics and intrinsics in :mod:`axis_ptz_ros2.optics`; both follow the
conventions written here, and neither converts units or signs.

Conventions (see docs/conventions.md and geometry-and-calibration.md §1-§5):

* ROS side (every topic, service and parameter): REP-103, radians. ``pan`` is yaw about the ``ptz_base`` +z
  axis, counter-clockwise positive (looking left); ``tilt`` is elevation, up positive.
* VAPIX side: degrees. The documented Axis convention is +pan = right (clockwise seen from above) and
  +tilt = up (VAPIX PTZ API, ``continuouspantiltmove``). :class:`VapixConvention` converts between the two; it
  is the *only* function that does, and it is configurable for a camera whose absolute pan turns the other way
  (``pan_direction="ccw"``) or that hangs from a ceiling (``mount="ceiling"``).
* Body frames x forward, y left, z up; optical frames x right, y down, z forward.
* Kinematic chain: ``T_base_opt(p, t) = T_base_ptz · Rz(p) · Trans(0, 0, h_tilt) · Ry(−t) · Trans(d_opt) ·
  R_body_opt``.
* Zoom: VAPIX units 1…9999 map to magnification ``m(z)`` through a per-camera monotone table (default:
  linear in magnification; each camera's HFOV and magnification from its ``config/<model>.yaml``);
  ``HFOV = 2·atan(tan(HFOV_w/2)/m)``.
* Pinhole for a W×H stream: ``fx = (W/2)/tan(HFOV/2)``, ``fy = fx·(H/W)·image_aspect`` (4:3 analogue image
  for the 214, so PAL 704×576 has fy = fx·12/11), ``cx = (W−1)/2``, ``cy = (H−1)/2``.
* Equirectangular panorama W×H: column 0 at azimuth +π, row 0 at elevation +π/2 (NIFTi/TRADR compatible).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum

import numpy as np
import numpy.typing as npt

from axis_ptz_ros2.optics import Intrinsics
from axis_ptz_ros2.transforms import (
    Q_BODY_OPT,
    R_BODY_OPT,
    FloatArray,
    Pose,
    Quaternion,
    Transform,
    Vector3,
    canonical_quaternion,
    quaternion_multiply,
    quaternion_rotate,
    rot_y,
    rot_z,
)


# --------------------------------------------------------------------------------------------------------
# VAPIX degrees <-> REP-103 radians: the only conversion in the project
# --------------------------------------------------------------------------------------------------------
class PanDirection(StrEnum):
    """Which way a *positive VAPIX pan* turns the camera, seen from above with the camera upright."""

    CW = "cw"  # Axis documentation: + pan = right (clockwise from above). Default.
    CCW = "ccw"


class Mount(StrEnum):
    """How the camera is mounted relative to ``ptz_base`` (whose z axis always points up)."""

    UPRIGHT = "upright"
    CEILING = "ceiling"  # upside down: the camera's own pan and tilt directions are mirrored


@dataclass(frozen=True, slots=True)
class VapixConvention:
    """Converts camera (VAPIX) pan/tilt degrees to REP-103 pan/tilt radians and back.

    For an upright camera with the documented Axis direction (``cw``): ``pan_ros = −radians(pan_vapix)``,
    ``tilt_ros = radians(tilt_vapix)``. ``ccw`` flips the pan sign; ``ceiling`` flips both (the camera's
    "right" and "up" are mirrored when it hangs upside down).
    """

    pan_direction: PanDirection = PanDirection.CW
    mount: Mount = Mount.UPRIGHT

    @property
    def _pan_sign(self) -> float:
        s = -1.0 if self.pan_direction is PanDirection.CW else 1.0
        return -s if self.mount is Mount.CEILING else s

    @property
    def _tilt_sign(self) -> float:
        return -1.0 if self.mount is Mount.CEILING else 1.0

    def to_ros(self, pan_deg: float, tilt_deg: float) -> tuple[float, float]:
        """VAPIX (pan°, tilt°) → REP-103 (pan rad, tilt rad)."""
        return self._pan_sign * math.radians(pan_deg), self._tilt_sign * math.radians(tilt_deg)

    def to_vapix(self, pan_rad: float, tilt_rad: float) -> tuple[float, float]:
        """REP-103 (pan rad, tilt rad) → VAPIX (pan°, tilt°)."""
        return self._pan_sign * math.degrees(pan_rad), self._tilt_sign * math.degrees(tilt_rad)

    def pan_rate_to_vapix(self, pan_rate: float) -> float:
        """Sign of a REP-103 pan rate as a VAPIX continuous pan speed (+ = camera's right)."""
        return self._pan_sign * pan_rate

    def tilt_rate_to_vapix(self, tilt_rate: float) -> float:
        """Sign of a REP-103 tilt rate as a VAPIX continuous tilt speed (+ = camera's up)."""
        return self._tilt_sign * tilt_rate

    def limits_to_ros(
        self, min_pan_deg: float, max_pan_deg: float, min_tilt_deg: float, max_tilt_deg: float
    ) -> tuple[float, float, float, float]:
        """VAPIX limit box → REP-103 (min_pan, max_pan, min_tilt, max_tilt) in radians."""
        p = sorted(self.to_ros(v, 0.0)[0] for v in (min_pan_deg, max_pan_deg))
        t = sorted(self.to_ros(0.0, v)[1] for v in (min_tilt_deg, max_tilt_deg))
        return p[0], p[1], t[0], t[1]


def wrap_angle(a: float) -> float:
    """Wrap to (−π, π]."""
    w = math.remainder(a, 2.0 * math.pi)
    return math.pi if w == -math.pi else w


# --------------------------------------------------------------------------------------------------------
# Kinematics of the pan/tilt head
# --------------------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class PtzKinematics:
    """Pan/tilt head geometry in ``ptz_base`` (metres): tilt axis ``h_tilt`` above the pan origin; optical
    centre at ``d_opt`` from the tilt axis in the tilted head frame (x forward, y left, z up)."""

    h_tilt: float = 0.0  # a model's own figures come from its camera-model file (``head:``)
    d_opt: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def head_to_ptz_base(self, pan: float, tilt: float) -> Transform:
        """``T_ptzbase_head``: the tilted head body frame (x along the optical axis) at REP-103 pan/tilt."""
        R = rot_z(pan) @ rot_y(-tilt)
        t = np.array([0.0, 0.0, self.h_tilt]) + R @ np.asarray(self.d_opt, dtype=np.float64)
        return Transform(R, t)

    def optical_in_ptz_base(self, pan: float, tilt: float) -> Transform:
        """``T_ptzbase_opt``: the optical frame (x right, y down, z forward) at REP-103 pan/tilt."""
        head = self.head_to_ptz_base(pan, tilt)
        return Transform(head.R @ R_BODY_OPT, head.t)

    def optical_pose(self, pan: float, tilt: float) -> Pose:
        """:meth:`optical_in_ptz_base` in plain floats (:class:`Pose`, for every state poll)."""
        sp, cp = math.sin(0.5 * pan), math.cos(0.5 * pan)
        st, ct = math.sin(-0.5 * tilt), math.cos(-0.5 * tilt)
        head: Quaternion = (-sp * st, cp * st, sp * ct, cp * ct)  # Rz(pan)·Ry(−tilt)
        dx, dy, dz = self.d_opt
        if dx == 0.0 and dy == 0.0 and dz == 0.0:
            t: Vector3 = (0.0, 0.0, self.h_tilt)
        else:
            rx, ry, rz = quaternion_rotate(head, self.d_opt)
            t = (rx, ry, self.h_tilt + rz)
        return Pose(t, canonical_quaternion(quaternion_multiply(head, Q_BODY_OPT)))

    def look_at(self, point_ptz_base: npt.ArrayLike, iterations: int = 50) -> tuple[float, float]:
        """Exact REP-103 (pan, tilt) that puts a point (in ``ptz_base``) on the optical axis.

        Exact for an optical centre on the optical axis through the tilt axis (``d_opt`` along x); lateral or
        vertical ``d_opt`` components are handled by a few fixed-point iterations (converges to < 1e-9 rad for
        offsets of centimetres at ranges of decimetres and more).
        """
        P = np.asarray(point_ptz_base, dtype=np.float64)
        pan = math.atan2(P[1], P[0])
        tilt = math.atan2(P[2] - self.h_tilt, math.hypot(P[0], P[1]))
        dy, dz = self.d_opt[1], self.d_opt[2]
        if dy == 0.0 and dz == 0.0:
            return pan, tilt
        for _ in range(iterations):
            head = self.head_to_ptz_base(pan, tilt)
            local = head.R.T @ (P - head.t)  # point in the head frame; want local y = local z = 0
            dpan = math.atan2(local[1], local[0])
            dtilt = math.atan2(local[2], math.hypot(local[0], local[1]))
            pan += dpan
            tilt += dtilt
            if abs(dpan) < 1e-12 and abs(dtilt) < 1e-12:
                break
        return pan, tilt


# --------------------------------------------------------------------------------------------------------
# Pointing
# --------------------------------------------------------------------------------------------------------
def pixel_direction_in_ptz_base(pan: float, tilt: float, u: float, v: float, intrinsics: Intrinsics) -> FloatArray:
    """Unit direction (in ``ptz_base`` orientation) of the ray through pixel (u, v) at REP-103 pan/tilt."""
    xn = (u - intrinsics.cx) / intrinsics.fx
    yn = (v - intrinsics.cy) / intrinsics.fy
    d = rot_z(pan) @ rot_y(-tilt) @ np.array([1.0, -xn, -yn])
    return np.asarray(d / np.linalg.norm(d), dtype=np.float64)


def center_on_pixel(pan: float, tilt: float, u: float, v: float, intrinsics: Intrinsics) -> tuple[float, float]:
    """Exact REP-103 (pan, tilt) that brings pixel (u, v) to the image centre, valid at any tilt.

    (``pan + atan(xn)`` is wrong whenever tilt ≠ 0; geometry-and-calibration.md §4.)
    """
    d = pixel_direction_in_ptz_base(pan, tilt, u, v, intrinsics)
    return math.atan2(d[1], d[0]), math.atan2(d[2], math.hypot(d[0], d[1]))


def direction_to_pan_tilt(d: npt.ArrayLike) -> tuple[float, float]:
    """Direction vector → (azimuth/pan, elevation/tilt) in REP-103 radians."""
    v = np.asarray(d, dtype=np.float64)
    return math.atan2(v[1], v[0]), math.atan2(v[2], math.hypot(v[0], v[1]))


def pan_tilt_to_direction(pan: float, tilt: float) -> FloatArray:
    """(azimuth, elevation) radians → unit direction vector."""
    return np.array([math.cos(tilt) * math.cos(pan), math.cos(tilt) * math.sin(pan), math.sin(tilt)])


# --------------------------------------------------------------------------------------------------------
# Equirectangular panorama
# --------------------------------------------------------------------------------------------------------
def direction_to_equirect(d: npt.ArrayLike, width: int, height: int) -> FloatArray:
    """Directions (…, 3) in the panorama frame → pixel coordinates (…, 2) (column 0 at az = +π)."""
    v = np.asarray(d, dtype=np.float64)
    az = np.arctan2(v[..., 1], v[..., 0])
    el = np.arctan2(v[..., 2], np.sqrt(v[..., 0] * v[..., 0] + v[..., 1] * v[..., 1]))  # sqrt: 10x np.hypot
    x = (0.5 - az / (2.0 * math.pi)) * width - 0.5
    y = (0.5 - el / math.pi) * height - 0.5
    return np.stack([x, y], -1)


def equirect_to_direction(x: npt.ArrayLike, y: npt.ArrayLike, width: int, height: int) -> FloatArray:
    """Panorama pixel coordinates → unit directions (…, 3) in the panorama frame."""
    az = math.pi - 2.0 * math.pi * (np.asarray(x, dtype=np.float64) + 0.5) / width
    el = math.pi / 2.0 - math.pi * (np.asarray(y, dtype=np.float64) + 0.5) / height
    ce = np.cos(el)
    return np.stack([ce * np.cos(az), ce * np.sin(az), np.sin(el)], -1)
