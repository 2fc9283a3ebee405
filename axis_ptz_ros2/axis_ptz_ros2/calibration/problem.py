"""The least-squares model of the extrinsic calibration (ROS-free): observations, projection with lens
distortion, one solve, its Jacobian, PnP initialisation and the geometric input checks.

Used by :func:`axis_ptz_ros2.calibration.solver.calibrate`; see that module for the model and the pipeline.
The unknowns are ``T`` (``T_base_ptz``, or ``T_reference_optical`` for a fixed camera: translation in metres
and a rotation vector ``ω`` with ``R = exp([ω]×)·R₀`` about the parent axes), optionally the tilt encoder
offset and, for the focal check only, a log focal scale.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares

from axis_ptz_ros2.calibration.correspondences import View
from axis_ptz_ros2.camera_info import CameraInfoData, distort_normalized, undistort_pixels
from axis_ptz_ros2.config import CameraModel
from axis_ptz_ros2.geometry import PtzKinematics
from axis_ptz_ros2.optics import Intrinsics
from axis_ptz_ros2.transforms import Transform

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]


# --------------------------------------------------------------------------------------------------------
# Rotation-vector helpers (transforms.py has matrices, rpy and quaternions but no so(3) exp/log)
# --------------------------------------------------------------------------------------------------------
def exp_so3(w: npt.ArrayLike) -> FloatArray:
    """Rotation matrix of a rotation vector (Rodrigues)."""
    v = np.asarray(w, dtype=np.float64)
    th = float(np.linalg.norm(v))
    K = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    if th < 1e-8:
        return np.asarray(np.eye(3) + K + 0.5 * (K @ K), dtype=np.float64)
    R = np.eye(3) + (math.sin(th) / th) * K + ((1.0 - math.cos(th)) / (th * th)) * (K @ K)
    return np.asarray(R, dtype=np.float64)


def log_so3(R: FloatArray) -> FloatArray:
    """Rotation vector of a rotation matrix (inverse of :func:`exp_so3`)."""
    c = max(-1.0, min(1.0, (float(np.trace(R)) - 1.0) / 2.0))
    th = math.acos(c)
    if th < 1e-7:
        return 0.5 * np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    if math.pi - th < 1e-4:
        # near π: axis from the symmetric part
        A = (R + np.eye(3)) / 2.0
        i = int(np.argmax(np.diag(A)))
        axis = A[:, i] / math.sqrt(max(A[i, i], 1e-12))
        return np.asarray(axis / np.linalg.norm(axis) * th, dtype=np.float64)
    w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    return np.asarray(w * (th / (2.0 * math.sin(th))), dtype=np.float64)


def rotation_angle(R: FloatArray) -> float:
    """Angle (rad) of a rotation matrix."""
    return float(np.linalg.norm(log_so3(R)))


def chordal_mean(rotations: Sequence[FloatArray], weights: Sequence[float] | None = None) -> FloatArray:
    """Chordal L2 mean of rotation matrices (projection of the weighted sum onto SO(3))."""
    w = np.ones(len(rotations)) if weights is None else np.asarray(weights, dtype=np.float64)
    M = sum((wi * Ri for wi, Ri in zip(w, rotations, strict=True)), np.zeros((3, 3)))
    U, _, Vt = np.linalg.svd(M)
    D = np.diag([1.0, 1.0, float(np.sign(np.linalg.det(U @ Vt)) or 1.0)])
    return np.asarray(U @ D @ Vt, dtype=np.float64)


def robust_average(candidates: Sequence[Transform]) -> Transform:
    """Robust mean of transforms: component-wise median translation, chordal mean rotation after dropping
    rotations further than 3× the median angular deviation (and > 2°) from a first mean."""
    Rs = [c.R for c in candidates]
    t = np.median(np.array([c.t for c in candidates]), axis=0)
    R = chordal_mean(Rs)
    dev = np.array([rotation_angle(R.T @ Ri) for Ri in Rs])
    keep = dev <= max(3.0 * float(np.median(dev)), math.radians(2.0))
    if keep.any():
        R = chordal_mean([Ri for Ri, k in zip(Rs, keep, strict=True) if k])
    return Transform(R, np.asarray(t, dtype=np.float64))


# --------------------------------------------------------------------------------------------------------
# The least-squares problem
# --------------------------------------------------------------------------------------------------------
class FixedHead:
    """The "head" of a fixed camera: the optical frame *is* the solved frame (T_reference_optical)."""

    def optical_in_ptz_base(self, pan: float, tilt: float) -> Transform:  # noqa: ARG002  (same API as the head)
        return Transform()


class Problem:
    """Flattened observations and the projection model (raw pixels: K and distortion per view)."""

    def __init__(self, views: Sequence[View], camera_model: CameraModel, fixed: bool = False) -> None:
        self.views = [v for v in views if v.points]
        self.fixed = fixed
        self.head: PtzKinematics | FixedHead = FixedHead() if fixed else camera_model.head
        z0 = float(camera_model.zoom.min_zoom)
        self.cinfo: list[CameraInfoData] = [
            camera_model.camera_info_at(v.zoom if (v.has_ptz and not fixed) else z0, v.image_width, v.image_height)
            for v in self.views
        ]
        self.intr: list[Intrinsics] = [ci.intrinsics() for ci in self.cinfo]
        X, uv, vidx, labels, pidx, lines = [], [], [], [], [], []
        for k, v in enumerate(self.views):
            for i, c in enumerate(v.points):
                X.append(c.point)
                uv.append(c.pixel)
                vidx.append(k)
                labels.append(c.label)
                pidx.append(i)
                lines.append(c.line)
        self.X = np.array(X, dtype=np.float64).reshape(-1, 3)
        self.uv = np.array(uv, dtype=np.float64).reshape(-1, 2)
        self.vidx = np.array(vidx, dtype=np.intp)
        self.labels = labels
        self.pidx = pidx
        self.lines = lines
        self.pans = np.array([0.0 if fixed else v.pan for v in self.views])
        self.tilts = np.array([0.0 if fixed else v.tilt for v in self.views])
        self.fx = np.array([self.intr[k].fx for k in vidx])
        self.fy = np.array([self.intr[k].fy for k in vidx])
        self.cx = np.array([self.intr[k].cx for k in vidx])
        self.cy = np.array([self.intr[k].cy for k in vidx])
        self.n = len(self.X)
        # views with lens distortion: (point mask, model, coefficients)
        self.distorted = [
            (self.vidx == k, ci.distortion_model, ci.coefficients)
            for k, ci in enumerate(self.cinfo)
            if ci.has_distortion
        ]
        # ideal (undistorted) pixels in the same K, for PnP initialisation and the ray-spread gate
        self.uv_ideal = self.uv.copy()
        for k, ci in enumerate(self.cinfo):
            sel = self.vidx == k
            if ci.has_distortion and sel.any():
                self.uv_ideal[sel] = undistort_pixels(self.uv[sel], ci)

    def camera_poses(self, T: Transform, tilt_offset: float) -> tuple[FloatArray, FloatArray]:
        """Per-view ``T_base_opt`` as stacked (V, 3, 3) rotations and (V, 3) translations."""
        V = len(self.views)
        Rs = np.empty((V, 3, 3))
        ts = np.empty((V, 3))
        for k in range(V):
            h = self.head.optical_in_ptz_base(float(self.pans[k]), float(self.tilts[k]) + tilt_offset)
            Rs[k] = T.R @ h.R
            ts[k] = T.R @ h.t + T.t
        return Rs, ts

    def view_pose(self, T: Transform, tilt_offset: float, k: int) -> Transform:
        """``T_base_opt`` of view ``k``."""
        return T @ self.head.optical_in_ptz_base(float(self.pans[k]), float(self.tilts[k]) + tilt_offset)

    def points_in_camera(self, T: Transform, tilt_offset: float) -> FloatArray:
        """Every 3-D point in the optical frame of its view (N, 3)."""
        Rs, ts = self.camera_poses(T, tilt_offset)
        d = self.X - ts[self.vidx]
        return np.asarray(np.einsum("nji,nj->ni", Rs[self.vidx], d), dtype=np.float64)

    def project(self, T: Transform, tilt_offset: float, focal_scale: float = 1.0) -> FloatArray:
        """Predicted raw pixels (N, 2), lens distortion included; points behind a camera are pushed far
        outside the image."""
        P = self.points_in_camera(T, tilt_offset)
        z = np.maximum(P[:, 2], 1e-3)
        xy = P[:, :2] / z[:, None]
        for sel, model, coeffs in self.distorted:
            xy[sel] = distort_normalized(xy[sel], model, coeffs)
        u = focal_scale * self.fx * xy[:, 0] + self.cx
        v = focal_scale * self.fy * xy[:, 1] + self.cy
        return np.stack([u, v], -1)

    def sigmas(self, T: Transform, tilt_offset: float, sigma_px: float, sigma_3d: float) -> FloatArray:
        """Per-point, per-axis σ (N, 2): ``σ² = σ_px² + (f·σ_3D/Z)²``."""
        z = np.maximum(self.points_in_camera(T, tilt_offset)[:, 2], 0.05)
        su = np.sqrt(sigma_px**2 + (self.fx * sigma_3d / z) ** 2)
        sv = np.sqrt(sigma_px**2 + (self.fy * sigma_3d / z) ** 2)
        return np.stack([su, sv], -1)

    def where(self, i: int, source: str | None) -> str:
        """``file:line`` (or view/index) of correspondence ``i`` for messages."""
        v = self.views[int(self.vidx[i])].name
        line = self.lines[i]
        loc = f"{source}:{line}" if source and line else (f"line {line}" if line else "")
        return f"{loc} (view {v!r}, point {self.pidx[i]})" if loc else f"view {v!r}, point {self.pidx[i]}"


@dataclass(slots=True)
class Params:
    """Parameter vector layout: [tx, ty, tz, ωx, ωy, ωz, (tilt_offset), (log focal scale)]."""

    R0: FloatArray
    tilt: bool
    focal: bool

    def size(self) -> int:
        return 6 + int(self.tilt) + int(self.focal)

    def unpack(self, x: FloatArray) -> tuple[Transform, float, float]:
        T = Transform(exp_so3(x[3:6]) @ self.R0, np.array(x[:3], dtype=np.float64))
        i = 6
        dt = 0.0
        if self.tilt:
            dt = float(x[i])
            i += 1
        s = math.exp(float(x[i])) if self.focal else 1.0
        return T, dt, s

    def pack(self, T: Transform, tilt_offset: float, focal_scale: float = 1.0) -> FloatArray:
        x = [*T.t.tolist(), *log_so3(T.R @ self.R0.T).tolist()]
        if self.tilt:
            x.append(tilt_offset)
        if self.focal:
            x.append(math.log(focal_scale))
        return np.array(x, dtype=np.float64)


@dataclass(slots=True)
class Fit:
    T: Transform
    tilt_offset: float
    focal_scale: float
    cost: float


def solve(
    prob: Problem,
    T0: Transform,
    tilt0: float,
    mask: BoolArray,
    sig: FloatArray,
    *,
    estimate_tilt: bool,
    estimate_focal: bool = False,
    focal0: float = 1.0,
    robust: bool,
    f_scale: float = 2.0,
) -> Fit:
    """One least-squares solve on the masked observations with fixed per-point σ."""
    par = Params(T0.R.copy(), estimate_tilt, estimate_focal)
    uv = prob.uv[mask]
    w = 1.0 / sig[mask]

    def fun(x: FloatArray) -> FloatArray:
        T, dt, s = par.unpack(x)
        pred = prob.project(T, dt, s)[mask]
        return np.asarray(((pred - uv) * w).reshape(-1), dtype=np.float64)

    x0 = par.pack(T0, tilt0, focal0)
    if robust:
        res = least_squares(fun, x0, method="trf", loss="soft_l1", f_scale=f_scale, x_scale="jac", max_nfev=200)
    elif 2 * int(mask.sum()) >= par.size():
        res = least_squares(fun, x0, method="lm", x_scale="jac", max_nfev=400)
    else:
        res = least_squares(fun, x0, method="trf", x_scale="jac", max_nfev=400)
    T, dt, s = par.unpack(np.asarray(res.x, dtype=np.float64))
    return Fit(T, dt, s, float(res.cost))


def jacobian(prob: Problem, fit: Fit, mask: BoolArray, sig: FloatArray, tilt: bool, focal: bool) -> FloatArray:
    """Central-difference Jacobian of the whitened residuals at ``fit`` (rotation about the parent axes)."""
    par = Params(fit.T.R.copy(), tilt, focal)
    x0 = par.pack(fit.T, fit.tilt_offset, fit.focal_scale)
    w = 1.0 / sig[mask]

    def fun(x: FloatArray) -> FloatArray:
        T, dt, s = par.unpack(x)
        return np.asarray((prob.project(T, dt, s)[mask] * w).reshape(-1), dtype=np.float64)

    steps = np.array([1e-5] * 3 + [1e-6] * 3 + [1e-6] * (len(x0) - 6))
    J = np.empty((2 * int(mask.sum()), len(x0)))
    for j in range(len(x0)):
        e = np.zeros(len(x0))
        e[j] = steps[j]
        J[:, j] = (fun(x0 + e) - fun(x0 - e)) / (2.0 * steps[j])
    return J


def whitened(prob: Problem, fit: Fit, sig: FloatArray) -> FloatArray:
    """Whitened residual components (N, 2) of every observation."""
    return np.asarray((prob.project(fit.T, fit.tilt_offset, fit.focal_scale) - prob.uv) / sig, dtype=np.float64)


# --------------------------------------------------------------------------------------------------------
# Initialisation
# --------------------------------------------------------------------------------------------------------
def pnp_view(prob: Problem, k: int, planar: bool) -> Transform | None:
    """Best PnP camera pose of view ``k`` as a ``T_base_ptz`` candidate (None if every method failed)."""
    return pnp_points(prob, prob.vidx == k, k, planar)


def pnp_points(prob: Problem, sel: BoolArray, k: int, planar: bool) -> Transform | None:
    """PnP on the selected points with view ``k``'s K and head pose (for a fixed camera: all its views when
    they share one K). None if every method failed or the views' K differ."""
    if any(not np.allclose(prob.intr[int(j)].K, prob.intr[k].K) for j in np.unique(prob.vidx[sel])):
        return None
    obj = np.ascontiguousarray(prob.X[sel])
    img = np.ascontiguousarray(prob.uv_ideal[sel])
    if len(obj) < 4:
        return None
    K = prob.intr[k].K
    methods = [cv2.SOLVEPNP_SQPNP, cv2.SOLVEPNP_EPNP]
    if len(obj) >= 6 or planar:
        methods.append(cv2.SOLVEPNP_ITERATIVE)
    if planar:
        methods.append(cv2.SOLVEPNP_IPPE)
    best: tuple[float, FloatArray, FloatArray] | None = None
    for flag in methods:
        try:
            ok, rvec, tvec = cv2.solvePnP(obj, img, K, None, flags=flag)
        except cv2.error:
            continue
        if not ok or not np.all(np.isfinite(rvec)) or not np.all(np.isfinite(tvec)):
            continue
        R_oc = exp_so3(np.asarray(rvec, dtype=np.float64).reshape(3))
        t_oc = np.asarray(tvec, dtype=np.float64).reshape(3)
        P = obj @ R_oc.T + t_oc
        if np.any(P[:, 2] <= 0):
            continue
        pred = prob.intr[k].project(P)
        err = float(np.sqrt(np.mean(np.sum((pred - img) ** 2, axis=1))))
        if best is None or err < best[0]:
            best = (err, R_oc, t_oc)
    if best is None:
        return None
    T_opt_base = Transform(best[1], best[2])
    head = prob.head.optical_in_ptz_base(float(prob.pans[k]), float(prob.tilts[k]))
    return T_opt_base.inverse() @ head.inverse()


# --------------------------------------------------------------------------------------------------------
# Gates that need no solution
# --------------------------------------------------------------------------------------------------------
def planarity_ratio(points: FloatArray) -> float:
    """Smallest / largest singular value of the centred 3-D points (0 = exactly coplanar or collinear)."""
    if len(points) < 3:
        return 0.0
    s = np.linalg.svd(points - points.mean(axis=0), compute_uv=False)
    return float(s[-1] / s[0]) if s[0] > 0 else 0.0


def angular_spread_deg(prob: Problem) -> float:
    """RMS angular spread (deg) of the observed rays (in ptz_base orientation) in their second-widest
    direction: √λ₂ of the scatter matrix of the unit ray directions (a narrow cone gives ~0)."""
    dirs = []
    for k in range(len(prob.views)):
        sel = prob.vidx == k
        rays = prob.intr[k].ray(prob.uv_ideal[sel, 0], prob.uv_ideal[sel, 1])
        R = prob.head.optical_in_ptz_base(float(prob.pans[k]), float(prob.tilts[k])).R
        d = rays @ R.T
        dirs.append(d / np.linalg.norm(d, axis=1, keepdims=True))
    D = np.concatenate(dirs)
    lam = np.sort(np.linalg.eigvalsh(D.T @ D / len(D)))[::-1]
    return math.degrees(math.sqrt(max(float(lam[1]), 0.0)))


# --------------------------------------------------------------------------------------------------------
# Input checks that need no solution
# --------------------------------------------------------------------------------------------------------
def duplicate_rows(prob: Problem) -> list[list[int]]:
    """Groups (≥ 2) of identical correspondences: same pixel and same 3-D point in views at the same camera
    pose (same pan/tilt/zoom and image size; every view of a fixed camera). Identical rows are one
    measurement counted several times: they would masquerade as independent evidence."""
    keys: dict[tuple[object, ...], list[int]] = {}
    for i in range(prob.n):
        v = prob.views[int(prob.vidx[i])]
        pose: tuple[object, ...] = (v.image_width, v.image_height)
        if not prob.fixed:
            pose += (round(float(v.pan), 9), round(float(v.tilt), 9), round(float(v.zoom), 3))
        key = (*pose, *np.round(prob.uv[i], 6).tolist(), *np.round(prob.X[i], 7).tolist())
        keys.setdefault(key, []).append(i)
    return [g for g in keys.values() if len(g) > 1]


def chi2(prob: Problem, fit: Fit, mask: BoolArray, sig: FloatArray) -> float:
    return float(np.sum(whitened(prob, fit, sig)[mask] ** 2))


def skew(a: FloatArray) -> FloatArray:
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
