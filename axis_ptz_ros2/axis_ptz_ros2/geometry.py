"""The one place where units, signs, frames and optics are defined (ROS-free, numpy only).

Conventions (see README "Conventions" and geometry-and-calibration.md §1-§5):

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
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]

# Optical frame axes expressed in the body frame: columns are optical x (right), y (down), z (forward).
R_BODY_OPT: FloatArray = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


# --------------------------------------------------------------------------------------------------------
# Rotations and rigid transforms
# --------------------------------------------------------------------------------------------------------
def rot_x(a: float) -> FloatArray:
    """Rotation matrix about +x by ``a`` radians."""
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(a: float) -> FloatArray:
    """Rotation matrix about +y by ``a`` radians."""
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(a: float) -> FloatArray:
    """Rotation matrix about +z by ``a`` radians."""
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rpy_to_matrix(roll: float, pitch: float, yaw: float) -> FloatArray:
    """REP-103 fixed-axis roll/pitch/yaw (x, then y, then z): ``R = Rz(yaw)·Ry(pitch)·Rx(roll)``."""
    return rot_z(yaw) @ rot_y(pitch) @ rot_x(roll)


def matrix_to_rpy(R: FloatArray) -> tuple[float, float, float]:
    """Inverse of :func:`rpy_to_matrix` (roll, pitch, yaw in radians)."""
    pitch = math.asin(max(-1.0, min(1.0, -float(R[2, 0]))))
    roll = math.atan2(float(R[2, 1]), float(R[2, 2]))
    yaw = math.atan2(float(R[1, 0]), float(R[0, 0]))
    return roll, pitch, yaw


def matrix_to_quaternion(R: FloatArray) -> tuple[float, float, float, float]:
    """Rotation matrix → unit quaternion ``(x, y, z, w)`` (ROS order), w ≥ 0."""
    m = np.asarray(R, dtype=np.float64)
    tr = float(m[0, 0] + m[1, 1] + m[2, 2])
    if tr > 0.0:
        s = math.sqrt(tr + 1.0) * 2.0
        w, x = 0.25 * s, (m[2, 1] - m[1, 2]) / s
        y, z = (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2]) * 2.0
        w, x = (m[2, 1] - m[1, 2]) / s, 0.25 * s
        y, z = (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s
    elif m[1, 1] > m[2, 2]:
        s = math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2]) * 2.0
        w, x = (m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s
        y, z = 0.25 * s, (m[1, 2] + m[2, 1]) / s
    else:
        s = math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1]) * 2.0
        w, x = (m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s
        y, z = (m[1, 2] + m[2, 1]) / s, 0.25 * s
    q = np.array([x, y, z, w], dtype=np.float64)
    q /= np.linalg.norm(q)
    if q[3] < 0.0:
        q = -q
    return float(q[0]), float(q[1]), float(q[2]), float(q[3])


def quaternion_to_matrix(x: float, y: float, z: float, w: float) -> FloatArray:
    """Unit quaternion ``(x, y, z, w)`` → rotation matrix."""
    n = math.sqrt(x * x + y * y + z * z + w * w)
    x, y, z, w = x / n, y / n, z / n, w / n
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


@dataclass(frozen=True, slots=True)
class Transform:
    """A rigid transform ``T_a_b``: maps points expressed in frame b into frame a (``p_a = R·p_b + t``)."""

    R: FloatArray = field(default_factory=lambda: np.eye(3))
    t: FloatArray = field(default_factory=lambda: np.zeros(3))

    @staticmethod
    def from_xyz_rpy(x: float, y: float, z: float, roll: float, pitch: float, yaw: float) -> Transform:
        """Build from a translation (m) and REP-103 roll/pitch/yaw (rad)."""
        return Transform(rpy_to_matrix(roll, pitch, yaw), np.array([x, y, z], dtype=np.float64))

    @staticmethod
    def from_matrix(M: FloatArray) -> Transform:
        """Build from a 4×4 homogeneous matrix."""
        return Transform(np.array(M[:3, :3], dtype=np.float64), np.array(M[:3, 3], dtype=np.float64))

    def matrix(self) -> FloatArray:
        """4×4 homogeneous matrix."""
        M = np.eye(4)
        M[:3, :3] = self.R
        M[:3, 3] = self.t
        return M

    def __matmul__(self, other: Transform) -> Transform:
        """Compose ``T_a_b @ T_b_c = T_a_c``."""
        return Transform(self.R @ other.R, self.R @ other.t + self.t)

    def inverse(self) -> Transform:
        """``T_b_a`` from ``T_a_b``."""
        Rt = self.R.T
        return Transform(Rt, -Rt @ self.t)

    def apply(self, points: npt.ArrayLike) -> FloatArray:
        """Transform points (shape (3,) or (N, 3)) from frame b into frame a."""
        p = np.asarray(points, dtype=np.float64)
        return np.asarray(p @ self.R.T + self.t, dtype=np.float64)

    def xyz_rpy(self) -> tuple[float, float, float, float, float, float]:
        """Translation (m) and roll/pitch/yaw (rad)."""
        r, p, y = matrix_to_rpy(self.R)
        return float(self.t[0]), float(self.t[1]), float(self.t[2]), r, p, y


# --------------------------------------------------------------------------------------------------------
# Rigid transforms in plain floats (the per-poll transforms)
# --------------------------------------------------------------------------------------------------------
Vector3 = tuple[float, float, float]
Quaternion = tuple[float, float, float, float]  #: (x, y, z, w), ROS order


def quaternion_multiply(a: Quaternion, b: Quaternion) -> Quaternion:
    """Hamilton product ``a·b`` (the rotation ``b`` first, then ``a``)."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    )


def quaternion_rotate(q: Quaternion, v: Vector3) -> Vector3:
    """``v`` rotated by the unit quaternion ``q``."""
    x, y, z, w = q
    vx, vy, vz = v
    # v + 2w(u×v) + 2u×(u×v), u = (x, y, z)
    cx, cy, cz = y * vz - z * vy, z * vx - x * vz, x * vy - y * vx
    return (
        vx + 2.0 * (w * cx + y * cz - z * cy),
        vy + 2.0 * (w * cy + z * cx - x * cz),
        vz + 2.0 * (w * cz + x * cy - y * cx),
    )


def _canonical(q: Quaternion) -> Quaternion:
    """Unit length, w ≥ 0 (as :func:`matrix_to_quaternion` returns them)."""
    x, y, z, w = q
    n = math.sqrt(x * x + y * y + z * z + w * w)
    if w < 0.0:
        n = -n
    return x / n, y / n, z / n, w / n


@dataclass(frozen=True, slots=True)
class Pose:
    """:class:`Transform` in plain floats: ``T_a_b`` as translation ``t`` and unit quaternion ``q`` (w ≥ 0).

    For what runs on every state poll (``/tf``, ``ptz/transform``): numpy's per-call overhead on 3-vectors and
    3×3 matrices made the head's transform and its quaternion cost 0.4 ms of CPU per message at 20 Hz (cold
    caches); the same in floats costs a fraction of that. Equal to the :class:`Transform` path within 1e-12
    (tests/unit/test_geometry.py).
    """

    t: Vector3 = (0.0, 0.0, 0.0)
    q: Quaternion = (0.0, 0.0, 0.0, 1.0)

    @staticmethod
    def from_transform(T: Transform) -> Pose:
        """The same transform in floats."""
        return Pose((float(T.t[0]), float(T.t[1]), float(T.t[2])), matrix_to_quaternion(T.R))

    def transform(self) -> Transform:
        """The same transform with numpy arrays."""
        return Transform(quaternion_to_matrix(*self.q), np.array(self.t, dtype=np.float64))

    def __matmul__(self, other: Pose) -> Pose:
        """Compose ``T_a_b @ T_b_c = T_a_c``."""
        rx, ry, rz = quaternion_rotate(self.q, other.t)
        tx, ty, tz = self.t
        return Pose((tx + rx, ty + ry, tz + rz), _canonical(quaternion_multiply(self.q, other.q)))


Q_BODY_OPT: Quaternion = matrix_to_quaternion(R_BODY_OPT)  #: :data:`R_BODY_OPT` as a quaternion


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
        return Pose(t, _canonical(quaternion_multiply(head, Q_BODY_OPT)))

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
# Zoom optics and intrinsics
# --------------------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class Intrinsics:
    """Pinhole intrinsics of one stream (pixels). Distortion is not modelled (plumb_bob zeros)."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float

    @property
    def K(self) -> FloatArray:
        """3×3 camera matrix."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def hfov(self) -> float:
        """Horizontal field of view (rad) between the outer pixel edges."""
        return 2.0 * math.atan((self.width / 2.0) / self.fx)

    @property
    def vfov(self) -> float:
        """Vertical field of view (rad) between the outer pixel edges."""
        return 2.0 * math.atan((self.height / 2.0) / self.fy)

    def ray(self, u: npt.ArrayLike, v: npt.ArrayLike) -> FloatArray:
        """Unnormalised optical-frame rays ``(x, y, 1)`` through pixel coordinates (u right, v down)."""
        uu = np.asarray(u, dtype=np.float64)
        vv = np.asarray(v, dtype=np.float64)
        return np.stack([(uu - self.cx) / self.fx, (vv - self.cy) / self.fy, np.ones(np.broadcast(uu, vv).shape)], -1)

    def project(self, points_opt: npt.ArrayLike) -> FloatArray:
        """Project optical-frame points (N, 3) to pixels (N, 2); points behind the camera give NaN."""
        p = np.atleast_2d(np.asarray(points_opt, dtype=np.float64))
        z = p[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            u = self.fx * p[:, 0] / z + self.cx
            v = self.fy * p[:, 1] / z + self.cy
        out = np.stack([u, v], -1)
        out[z <= 0] = np.nan
        return out

    def scaled(self, width: int, height: int) -> Intrinsics:
        """The same optics for another stream size of the same sensor (resolution change)."""
        sx, sy = width / self.width, height / self.height
        return Intrinsics(width, height, self.fx * sx, self.fy * sy, (width - 1) / 2.0, (height - 1) / 2.0)


class ZoomCurve(StrEnum):
    """Shape of the zoom-units → magnification curve when no explicit table is configured."""

    LINEAR = "linear"  # m = 1 + (M−1)·t  (every published Axis zoomSteps table)
    LOG = "log"  # m = M**t


#: The fields a zoom model must be given (the optics); the others have neutral defaults (VAPIX 1…9999, linear
#: curve, a 4:3 frame, no digital zoom).
ZOOM_REQUIRED = ("hfov_wide_deg", "max_magnification")


@dataclass(frozen=True, slots=True)
class ZoomModel:
    """Zoom units ↔ magnification ↔ field of view for one camera model.

    ``table`` (optional) is a monotone list of ``(zoom_units, magnification)`` pairs (e.g. from a camera's
    ``zoomSteps`` attribute or a measurement); it is interpolated in log-magnification. Without a table the
    ``curve`` model with ``max_magnification`` at ``max_zoom`` is used.

    Digital zoom (modern Axis PTZ, ``PTZ.Support.S1.DigitalZoom=true``, ``MaxZoom=19999``): with
    ``optical_max_zoom`` set (e.g. 9999), the curve reaches ``max_magnification`` there and the units above it
    add ``digital_max_magnification``× linearly (vapix.md §8.3). Pixel aspect: ``square_pixels=False`` (the
    214) stretches the physical ``image_aspect`` frame onto any stream size (PAL 704×576 → fy = fx·12/11);
    ``square_pixels=True`` (a digital sensor of aspect ``image_aspect``) keeps fx = fy and uses the full
    width for streams at least as wide as the sensor, else the full height (sides cropped).
    """

    hfov_wide_deg: float  # no default: a camera model's optics come from its file (config/<model>.yaml)
    max_magnification: float
    min_zoom: int = 1
    max_zoom: int = 9999
    curve: ZoomCurve = ZoomCurve.LINEAR
    image_aspect: float = 4.0 / 3.0  # physical width/height of the full image (4:3 analogue for the 214)
    table: tuple[tuple[float, float], ...] = ()
    square_pixels: bool = False
    optical_max_zoom: int = 0  # 0: no digital zoom (max_zoom is the optical tele end)
    digital_max_magnification: float = 1.0

    def __post_init__(self) -> None:
        """Validate the configuration."""
        if self.optical_max_zoom and not self.min_zoom < self.optical_max_zoom <= self.max_zoom:
            raise ValueError("optical_max_zoom must lie in (min_zoom, max_zoom]")
        if self.digital_max_magnification < 1.0:
            raise ValueError(f"digital_max_magnification must be >= 1, got {self.digital_max_magnification}")
        if self.image_aspect <= 0.0:
            raise ValueError(f"image_aspect must be positive, got {self.image_aspect}")
        if not 0.0 < self.hfov_wide_deg < 180.0:
            raise ValueError(f"hfov_wide_deg must be in (0, 180), got {self.hfov_wide_deg}")
        if self.max_magnification < 1.0:
            raise ValueError(f"max_magnification must be >= 1, got {self.max_magnification}")
        if self.max_zoom <= self.min_zoom:
            raise ValueError("max_zoom must be greater than min_zoom")
        if self.table:
            zs = [z for z, _ in self.table]
            ms = [m for _, m in self.table]
            if any(b <= a for a, b in zip(zs, zs[1:], strict=False)) or any(
                b < a for a, b in zip(ms, ms[1:], strict=False)
            ):
                raise ValueError("zoom table must be strictly increasing in units and monotone in magnification")

    @staticmethod
    def from_dict(d: dict[str, Any]) -> ZoomModel:
        """Build from a configuration mapping (keys as the dataclass fields; ``table`` as [[z, m], ...])."""
        kw: dict[str, Any] = dict(d)
        missing = [k for k in ZOOM_REQUIRED if k not in kw]
        if missing:
            raise ValueError(f"missing key(s) {missing} (the optics: wide-end HFOV in degrees, tele magnification)")
        if "curve" in kw:
            kw["curve"] = ZoomCurve(kw["curve"])
        if "table" in kw:
            kw["table"] = tuple((float(z), float(m)) for z, m in kw["table"])
        return ZoomModel(**kw)

    def clamp(self, zoom: float) -> float:
        """Clamp zoom units into [min_zoom, max_zoom]."""
        return min(max(float(zoom), float(self.min_zoom)), float(self.max_zoom))

    def magnification(self, zoom: float) -> float:
        """Optical magnification at ``zoom`` units (1 at the wide end)."""
        z = self.clamp(zoom)
        if self.table:
            zs = np.array([p[0] for p in self.table])
            lm = np.log(np.array([p[1] for p in self.table]))
            return float(np.exp(np.interp(z, zs, lm)))
        zo = self._optical_end
        if z > zo:  # digital zoom: linear in magnification on top of the optical tele end
            return self.max_magnification * (
                1.0 + (self.digital_max_magnification - 1.0) * (z - zo) / (self.max_zoom - zo)
            )
        t = (z - self.min_zoom) / (zo - self.min_zoom)
        if self.curve is ZoomCurve.LOG:
            return float(self.max_magnification**t)
        return 1.0 + (self.max_magnification - 1.0) * t

    def zoom_for_magnification(self, magnification: float) -> float:
        """Inverse of :meth:`magnification` (zoom units, float; clamped to the range)."""
        m = min(max(magnification, self.magnification(self.min_zoom)), self.magnification(self.max_zoom))
        if self.table:
            zs = np.array([p[0] for p in self.table])
            lm = np.log(np.array([p[1] for p in self.table]))
            return float(np.interp(math.log(m), lm, zs))
        zo = self._optical_end
        if m > self.max_magnification and zo < self.max_zoom and self.digital_max_magnification > 1.0:
            frac = (m / self.max_magnification - 1.0) / (self.digital_max_magnification - 1.0)
            return zo + frac * (self.max_zoom - zo)
        if self.curve is ZoomCurve.LOG:
            t = math.log(m) / math.log(self.max_magnification) if self.max_magnification > 1 else 0.0
        else:
            t = (m - 1.0) / (self.max_magnification - 1.0) if self.max_magnification > 1 else 0.0
        return self.min_zoom + t * (zo - self.min_zoom)

    @property
    def _optical_end(self) -> int:
        """Zoom units of the optical tele end (``max_zoom`` without digital zoom)."""
        return self.optical_max_zoom if self.optical_max_zoom else self.max_zoom

    def hfov(self, zoom: float) -> float:
        """Horizontal field of view (rad) at ``zoom`` units."""
        half = math.tan(math.radians(self.hfov_wide_deg) / 2.0) / self.magnification(zoom)
        return 2.0 * math.atan(half)

    def zoom_for_hfov(self, hfov: float) -> float:
        """Zoom units that give a horizontal field of view of ``hfov`` radians (clamped)."""
        m = math.tan(math.radians(self.hfov_wide_deg) / 2.0) / math.tan(hfov / 2.0)
        return self.zoom_for_magnification(m)

    def intrinsics(self, zoom: float, width: int, height: int) -> Intrinsics:
        """Pinhole intrinsics of a ``width``×``height`` stream at ``zoom`` units."""
        half = math.tan(self.hfov(zoom) / 2.0)
        if self.square_pixels:
            if width / height >= self.image_aspect - 1e-9:
                fx = (width / 2.0) / half
            else:  # narrower than the sensor: full height, sides cropped
                fx = (height / 2.0) / (half / self.image_aspect)
            fy = fx
        else:
            fx = (width / 2.0) / half
            fy = fx * (height / width) * self.image_aspect
        return Intrinsics(width, height, fx, fy, (width - 1) / 2.0, (height - 1) / 2.0)


#: The Axis 214's optics as config/axis214.yaml gives them, for the simulator's world loader (its fallback when a
#: world file has no ``ptz.zoom_model``). The driver, the calibration and the nodes read config/axis214.yaml;
#: tests/unit/test_camera_facts.py keeps this copy equal to it.
AXIS_214_ZOOM = ZoomModel(hfov_wide_deg=47.98, max_magnification=18.88)


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
