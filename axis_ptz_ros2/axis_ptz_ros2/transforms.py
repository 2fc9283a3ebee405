"""Rotations and rigid transforms: matrices and quaternions (numpy) and the same in plain floats (ROS-free).

Frames as :mod:`axis_ptz_ros2.geometry` defines them (body frames x forward, y left, z up; optical frames x right,
y down, z forward); quaternions ``(x, y, z, w)`` in ROS order. ``T_a_b`` maps points expressed in frame b into
frame a.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

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


def canonical_quaternion(q: Quaternion) -> Quaternion:
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
        return Pose((tx + rx, ty + ry, tz + rz), canonical_quaternion(quaternion_multiply(self.q, other.q)))


Q_BODY_OPT: Quaternion = matrix_to_quaternion(R_BODY_OPT)  #: :data:`R_BODY_OPT` as a quaternion
