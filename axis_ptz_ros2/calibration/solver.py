"""Extrinsic calibration of the PTZ base against the laser frame from picked 2-D/3-D pairs (ROS-free).

Model (geometry-and-calibration.md §1, §6; thesis §6.4)::

    T_base_opt(p_k, t_k) = T_base_ptz · head(p_k + pan_offset, t_k + tilt_offset)
    u_ki = π(K(z_k), T_base_opt(p_k, t_k)⁻¹ · X_i)

with ``head = PtzKinematics.optical_in_ptz_base`` and ``K(z) = ZoomModel.intrinsics(z, W, H)``. The unknowns
are ``T_base_ptz`` (6 DoF: translation in metres and a rotation vector ``ω`` with ``R = exp([ω]×)·R₀``
around the current estimate ``R₀``, i.e. a rotation about the *parent* (base_link) axes) and optionally the
tilt encoder offset.

The pan encoder offset is *not* separately observable: ``head(p + δ) = Rz(δ)·head(p)`` exactly (the pan axis
is the ptz_base z axis and the tilt-axis height is on it), so any pan offset is absorbed, without loss, into
the yaw of ``T_base_ptz``; ``pan_offset`` is therefore reported as 0 and the mount's yaw carries it.

Pipeline (:func:`calibrate`):

1. Gate the input: enough points (≥ ``min_points`` in total, a view with ≥ 4 for PnP), not a single view of a
   nearly coplanar point set, enough angular spread of the observed rays.
2. Per-view PnP (SQPnP, EPnP, iterative; IPPE for planar sets) on the view's zoom-correct K; each camera pose
   gives a ``T_base_ptz`` candidate through the known head pose. Multi-start from the candidates and their
   robust average.
3. Joint robust refinement over all views (``scipy.optimize.least_squares``, TRF with a soft-L1 loss on
   residuals whitened by ``σ_i² = σ_px² + (f·σ_3D/Z_i)²``), outlier rejection at ``k·σ_i``, and a final
   non-robust Levenberg–Marquardt refit on the inliers (iterated until the inlier set is stable).
4. Covariance ``Σ = (JᵀWJ)⁻¹`` at the optimum, inflated by ``covariance_inflation`` (on σ), reported as 6×6
   (x, y, z, rotX, rotY, rotZ). Gates on the predicted σ (degeneracy), on the normalised RMS (inconsistent
   data) and on a focal-length check (a global focal scale fitted as a diagnostic).
5. Held-out reprojection error: leave-one-view-out refits (≥ 3 views) or k random point folds.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import cv2
import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares

from axis_ptz_ros2.calibration.correspondences import View
from axis_ptz_ros2.camera_info import CameraInfoData, distort_normalized, undistort_pixels
from axis_ptz_ros2.config import CameraModel, MountConfig
from axis_ptz_ros2.geometry import Intrinsics, PtzKinematics, Transform

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

HoldoutMode = Literal["auto", "views", "points", "none"]


class CalibrationRefused(Exception):  # noqa: N818  (public API name)
    """The data cannot give a trustworthy mount; ``reason`` says why, ``result`` holds the diagnostics if a
    solution was computed (``result.refused_reason == reason``)."""

    def __init__(self, reason: str, result: CalibrationResult | None = None) -> None:
        super().__init__(reason)
        self.reason = reason
        self.result = result


# --------------------------------------------------------------------------------------------------------
# Rotation-vector helpers (geometry.py has matrices, rpy and quaternions but no so(3) exp/log)
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
# Results
# --------------------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class PointResidual:
    """Reprojection residual of one correspondence at the final estimate."""

    view: str
    index: int  # index of the point within its view
    label: str
    pixel: tuple[float, float]  # measured (px)
    predicted: tuple[float, float]  # reprojected (px)
    error_px: float  # ‖predicted − measured‖ (px)
    normalised: float  # error divided by the point's σ_i (dimensionless)
    inlier: bool


@dataclass(frozen=True, slots=True)
class FocalCheck:
    """Diagnostic fit of a global focal-length scale ``s`` (fx, fy × s in every view).

    The scale is fitted on the inliers the fixed-focal fit selected (no re-selection, hence no selection
    bias in favour of another focal length). ``sigma`` uses the residuals' own scatter when it exceeds the
    assumed noise. Significance needs all of: an F-test of the nested fits with its proper degrees of freedom
    (``p_value`` below ``alpha``), a deviation beyond ``tolerance`` and 3σ, and a lower cross-validated
    (k-fold, held-out points) error with the free focal than with the model's.
    """

    scale: float  # best-fit s (1 = the camera model is right); NaN when not computed
    sigma: float  # 1σ of s
    rms_px_model: float  # inlier RMS (px) with the camera model's focal length
    rms_px_fitted: float  # inlier RMS (px) with the fitted scale, same points
    delta_chi2: float  # χ² drop from freeing the scale on the same points
    flagged: bool  # significant (see above)
    message: str
    f_stat: float = math.nan  # F = Δχ² / (χ²_free / dof)
    p_value: float = math.nan  # P(F(1, dof) ≥ f_stat)
    dof: int = 0
    cv_rms_model: float = math.nan  # k-fold held-out whitened RMS with the model's focal length
    cv_rms_fitted: float = math.nan  # ... with a free focal scale


@dataclass(frozen=True, slots=True)
class ViewResult:
    """Per-view outcome: the camera (optical frame) pose in the reference (laser/base) frame and its errors."""

    name: str
    T_reference_optical: Transform
    sigma_translation_m: tuple[float, float, float]  # 1σ x, y, z of the optical centre (reference axes)
    sigma_rotation_rad: tuple[float, float, float]  # 1σ rotation about the reference x, y, z axes
    rms_px: float  # RMS of this view's inlier residuals (raw pixels)
    holdout_rms_px: float  # RMS of this view's held-out errors (NaN if none held out)
    inliers: tuple[str, ...]  # labels (or "#index") of the inliers
    outliers: tuple[str, ...]


@dataclass(frozen=True, slots=True)
class CalibrationResult:
    """Outcome of :func:`calibrate`. ``transform`` is ``T_base_ptz`` (ptz_base in the base/laser frame) or,
    for a fixed camera, ``T_reference_optical``. ``solved`` is False when the refusal came before any solution
    (then the transform is the identity and σ infinite)."""

    transform: Transform
    covariance: FloatArray  # 6×6 (x, y, z m; rotX, rotY, rotZ rad about the parent axes), inflated
    pan_offset: float  # rad; always 0 (absorbed into the mount yaw, see module docstring)
    tilt_offset: float  # rad (0 unless estimate_encoder_offsets)
    tilt_offset_sigma: float  # rad (0 when not estimated)
    residuals: tuple[PointResidual, ...]
    rms_px: float  # RMS of the inlier 2-D residual norms (px)
    normalised_rms: float  # RMS of the inlier whitened residual components (≈ 1 when σ's are right)
    holdout_rms_px: float  # RMS of held-out 2-D errors (px); NaN if not computed
    holdout_p95_px: float
    holdout_mode: str
    inliers: BoolArray  # per correspondence, in file order (views, then points)
    focal_check: FocalCheck
    n_views: int
    n_points: int
    sigma_px: float
    sigma_3d_m: float
    start: str  # which initial candidate won the multi-start
    refused_reason: str | None = None
    notes: tuple[str, ...] = field(default_factory=tuple)
    views: tuple[ViewResult, ...] = field(default_factory=tuple)
    fixed: bool = False
    solved: bool = True
    warnings: tuple[str, ...] = field(default_factory=tuple)

    @property
    def n_inliers(self) -> int:
        """Number of correspondences used in the final fit."""
        return int(np.count_nonzero(self.inliers))

    @property
    def sigma_translation_m(self) -> FloatArray:
        """1σ of x, y, z (m)."""
        return np.sqrt(np.diag(self.covariance)[:3])

    @property
    def sigma_rotation_rad(self) -> FloatArray:
        """1σ of the rotation about x, y, z of the parent frame (rad)."""
        return np.sqrt(np.diag(self.covariance)[3:])

    def xyz_rpy(self) -> tuple[float, float, float, float, float, float]:
        """Translation (m) and REP-103 roll/pitch/yaw (rad) of ``transform``."""
        return self.transform.xyz_rpy()

    def to_mount_config(
        self, parent_frame: str = "base_link", child_frame: str = "axis_ptz_base", comment: str | None = None
    ) -> MountConfig:
        """A :class:`~axis_ptz_ros2.config.MountConfig` (with covariance) for ``config.save_mount``."""
        if comment is None:
            comment = (
                f"axis_calibrate: {self.n_inliers}/{self.n_points} points in {self.n_views} views, "
                f"RMS {self.rms_px:.2f} px, held-out RMS {self.holdout_rms_px:.2f} px ({self.holdout_mode}), "
                f"sigma_xyz_cm {np.round(self.sigma_translation_m * 100.0, 2).tolist()}, "
                f"sigma_rot_deg {np.round(np.degrees(self.sigma_rotation_rad), 3).tolist()}"
            )
        return MountConfig(
            transform=self.transform,
            parent_frame=parent_frame,
            child_frame=child_frame,
            pan_offset=self.pan_offset,
            tilt_offset=self.tilt_offset,
            covariance=tuple(float(v) for v in self.covariance.reshape(-1)),
            comment=comment,
        )


# --------------------------------------------------------------------------------------------------------
# The least-squares problem
# --------------------------------------------------------------------------------------------------------
class _FixedHead:
    """The "head" of a fixed camera: the optical frame *is* the solved frame (T_reference_optical)."""

    def optical_in_ptz_base(self, pan: float, tilt: float) -> Transform:  # noqa: ARG002  (same API as the head)
        return Transform()


class _Problem:
    """Flattened observations and the projection model (raw pixels: K and distortion per view)."""

    def __init__(self, views: Sequence[View], camera_model: CameraModel, fixed: bool = False) -> None:
        self.views = [v for v in views if v.points]
        self.fixed = fixed
        self.head: PtzKinematics | _FixedHead = _FixedHead() if fixed else camera_model.head
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
class _Params:
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
class _Fit:
    T: Transform
    tilt_offset: float
    focal_scale: float
    cost: float


def _solve(
    prob: _Problem,
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
) -> _Fit:
    """One least-squares solve on the masked observations with fixed per-point σ."""
    par = _Params(T0.R.copy(), estimate_tilt, estimate_focal)
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
    return _Fit(T, dt, s, float(res.cost))


def _jacobian(prob: _Problem, fit: _Fit, mask: BoolArray, sig: FloatArray, tilt: bool, focal: bool) -> FloatArray:
    """Central-difference Jacobian of the whitened residuals at ``fit`` (rotation about the parent axes)."""
    par = _Params(fit.T.R.copy(), tilt, focal)
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


def _whitened(prob: _Problem, fit: _Fit, sig: FloatArray) -> FloatArray:
    """Whitened residual components (N, 2) of every observation."""
    return np.asarray((prob.project(fit.T, fit.tilt_offset, fit.focal_scale) - prob.uv) / sig, dtype=np.float64)


# --------------------------------------------------------------------------------------------------------
# Initialisation
# --------------------------------------------------------------------------------------------------------
def _pnp_view(prob: _Problem, k: int, planar: bool) -> Transform | None:
    """Best PnP camera pose of view ``k`` as a ``T_base_ptz`` candidate (None if every method failed)."""
    return _pnp_points(prob, prob.vidx == k, k, planar)


def _pnp_points(prob: _Problem, sel: BoolArray, k: int, planar: bool) -> Transform | None:
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


def angular_spread_deg(prob: _Problem) -> float:
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
def duplicate_rows(prob: _Problem) -> list[list[int]]:
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


class CalibrationInputError(ValueError):
    """The views are not usable as given (e.g. a PTZ solve with views that have no pan/tilt)."""


# --------------------------------------------------------------------------------------------------------
# The public entry point
# --------------------------------------------------------------------------------------------------------
def calibrate(
    views: Sequence[View],
    camera_model: CameraModel,
    *,
    fixed: bool = False,
    estimate_encoder_offsets: bool = False,
    sigma_px: float = 1.0,
    sigma_3d_m: float = 0.02,
    robust: bool = True,
    outlier_k: float = 3.0,
    holdout_fraction: float = 0.2,
    holdout_mode: HoldoutMode = "auto",
    initial: Transform | None = None,
    n_starts: int = 3,
    min_points: int = 6,
    min_planarity_ratio: float = 0.1,
    min_angular_spread_deg: float = 2.0,
    max_sigma_translation_m: float = math.inf,
    max_sigma_rotation_deg: float = math.inf,
    max_normalised_rms: float = math.inf,
    min_inlier_fraction: float = 0.7,
    covariance_inflation: float = 1.5,
    focal_tolerance: float = 0.02,
    focal_alpha: float = 1e-3,
    refuse_on_focal_mismatch: bool = False,
    raise_on_refusal: bool = True,
    source: str | None = None,
    seed: int = 0,
) -> CalibrationResult:
    """Estimate ``T_base_ptz`` (and optionally the tilt encoder offset) from several views, or with
    ``fixed=True`` the pose ``T_reference_optical`` of a fixed camera (pan/tilt ignored; one view suffices
    when its points determine the pose).

    ``views`` hold the *reported* pan/tilt (REP-103 rad) and zoom of each view with its picked raw pixel /
    laser-point pairs; ``camera_model`` supplies the intrinsics (a measured ``camera_info`` with distortion,
    or the nominal zoom curve) and the head kinematics. ``sigma_px`` (px, per axis) and ``sigma_3d_m`` (m,
    per axis) are the picking noise; they weight the fit and scale the covariance (which is further scaled
    by the normalised RMS when the residuals are larger than these σ say).

    Refuses (:class:`CalibrationRefused`, or with ``raise_on_refusal=False`` a result with ``refused_reason``
    set — also before any solution exists, then ``solved`` is False) only when the data cannot determine the
    pose: too few points, identical rows, a single pose of nearly coplanar points, rays in a too narrow cone,
    singular normal equations, too few inliers. ``max_sigma_translation_m`` / ``max_sigma_rotation_deg`` /
    ``max_normalised_rms`` / ``refuse_on_focal_mismatch`` make it stricter. ``source`` (the file name) is
    used in messages that point at rows. Raises :class:`CalibrationInputError` for unusable input.
    """
    notes: list[str] = []
    warnings: list[str] = []
    if not fixed:
        bad = [v for v in views if v.points and not v.has_ptz]
        if bad:
            where = f"{source}:{bad[0].line}" if source and bad[0].line else f"view {bad[0].name!r}"
            raise CalibrationInputError(
                f"{where}: view {bad[0].name!r} has no pan/tilt/zoom; a PTZ calibration needs them "
                "(use --fixed / fixed=True for a fixed camera)"
            )
    prob = _Problem(views, camera_model, fixed)

    def refuse(reason: str, result: CalibrationResult | None = None) -> CalibrationResult:
        res = _replace_reason(result, reason) if result is not None else _unsolved(prob, reason, sigma_px, sigma_3d_m)
        if raise_on_refusal:
            raise CalibrationRefused(reason, result if result is None else res)
        return res

    if prob.n < min_points:
        return refuse(f"too few points: {prob.n} correspondences in total, at least {min_points} needed")
    dups = duplicate_rows(prob)
    if dups:
        groups = "; ".join(" = ".join(prob.where(i, source) for i in g) for g in dups[:5])
        more = f" (and {len(dups) - 5} more groups)" if len(dups) > 5 else ""
        return refuse(
            f"identical rows: {sum(len(g) for g in dups)} correspondences repeat the same pixel and 3-D point "
            f"in the same camera pose and would count as independent evidence: {groups}{more}; remove the copies"
        )
    per_view = np.bincount(prob.vidx, minlength=len(prob.views))
    n_views = len(prob.views)
    pose_keys = {(round(float(p), 4), round(float(t), 4)) for p, t in zip(prob.pans, prob.tilts, strict=True)}
    if initial is None and not np.any(per_view >= 4) and not (fixed and prob.n >= 4):
        return refuse("too few points per view: no view has the 4 correspondences PnP initialisation needs")
    pr = planarity_ratio(prob.X)
    if len(pose_keys) == 1 and pr < min_planarity_ratio:
        return refuse(
            f"degenerate geometry: a single camera pose of nearly coplanar points (planarity ratio {pr:.3f} < "
            f"{min_planarity_ratio}); add points off the plane" + ("" if fixed else " or views at other pan/tilt")
        )
    spread = angular_spread_deg(prob)
    if spread < min_angular_spread_deg:
        return refuse(
            f"degenerate geometry: angular spread of the rays {spread:.2f}° < {min_angular_spread_deg}°; "
            "spread the points over the image" + ("" if fixed else " and add views at other pan/tilt")
        )

    # ---- initial candidates -------------------------------------------------------------------------
    planar = pr < min_planarity_ratio
    cands: list[tuple[str, Transform]] = []
    if initial is not None:
        cands.append(("initial", initial))
    if fixed and len(prob.views) > 1:
        c = _pnp_points(prob, np.ones(prob.n, dtype=bool), 0, planar)
        if c is not None:
            cands.append(("pnp:all", c))
    for k in range(n_views):
        if per_view[k] >= 4:
            c = _pnp_view(prob, k, planar)
            if c is not None:
                cands.append((f"pnp:{prob.views[k].name}", c))
    if not cands:
        return refuse("initialisation failed: PnP found no camera pose in any view")
    if len(cands) > 1:
        cands.append(("robust-average", robust_average([c for _, c in cands])))

    all_mask = np.ones(prob.n, dtype=bool)

    def robust_cost(T: Transform) -> float:
        sig = prob.sigmas(T, 0.0, sigma_px, sigma_3d_m)
        r = np.linalg.norm(_whitened(prob, _Fit(T, 0.0, 1.0, 0.0), sig), axis=1)
        return float(np.sum(np.sqrt(1.0 + (r / 2.0) ** 2) - 1.0))

    ranked = sorted(cands, key=lambda c: robust_cost(c[1]))[: max(1, n_starts)]
    best: tuple[str, _Fit] | None = None
    for name, T0 in ranked:
        sig = prob.sigmas(T0, 0.0, sigma_px, sigma_3d_m)
        fit = _solve(prob, T0, 0.0, all_mask, sig, estimate_tilt=False, robust=robust)
        if estimate_encoder_offsets:
            sig = prob.sigmas(fit.T, 0.0, sigma_px, sigma_3d_m)
            fit = _solve(prob, fit.T, 0.0, all_mask, sig, estimate_tilt=True, robust=robust)
        if best is None or fit.cost < best[1].cost:
            best = (name, fit)
    assert best is not None
    start, fit = best

    # ---- outlier rejection and final non-robust refit --------------------------------------------------
    mask = all_mask.copy()
    for _ in range(4):
        sig = prob.sigmas(fit.T, fit.tilt_offset, sigma_px, sigma_3d_m)
        r = np.linalg.norm(_whitened(prob, fit, sig), axis=1)
        new_mask = r <= outlier_k if robust else all_mask.copy()
        if new_mask.sum() < min_points:
            new_mask = r <= np.sort(r)[min(min_points, prob.n) - 1]
        changed = not np.array_equal(new_mask, mask)
        mask = new_mask
        fit = _solve(prob, fit.T, fit.tilt_offset, mask, sig, estimate_tilt=estimate_encoder_offsets, robust=False)
        if not changed:
            break
    sig = prob.sigmas(fit.T, fit.tilt_offset, sigma_px, sigma_3d_m)
    wres = _whitened(prob, fit, sig)
    pred = prob.project(fit.T, fit.tilt_offset)
    err = np.linalg.norm(pred - prob.uv, axis=1)
    rms_px = float(np.sqrt(np.mean(err[mask] ** 2)))
    n_par = 6 + int(estimate_encoder_offsets)
    dof = max(2 * int(mask.sum()) - n_par, 1)
    normalised_rms = float(np.sqrt(np.sum(wres[mask] ** 2) / dof))

    # ---- covariance ---------------------------------------------------------------------------------
    J = _jacobian(prob, fit, mask, sig, estimate_encoder_offsets, False)
    JtJ = J.T @ J
    d = np.sqrt(np.maximum(np.diag(JtJ), 1e-300))
    corr_cond = np.linalg.cond(JtJ / np.outer(d, d))
    singular = 2 * int(mask.sum()) < n_par or not np.isfinite(corr_cond) or corr_cond > 1e12
    if singular:
        cov_full = np.full((JtJ.shape[0], JtJ.shape[0]), np.inf)
    else:
        # σ's that under-state the actual scatter would make Σ optimistic: scale by the normalised RMS
        scatter = max(normalised_rms, 1.0)
        cov_full = np.linalg.inv(JtJ) * (covariance_inflation * scatter) ** 2
        cov_full = 0.5 * (cov_full + cov_full.T)
    cov = np.asarray(cov_full[:6, :6], dtype=np.float64)
    tilt_sigma = float(math.sqrt(cov_full[6, 6])) if estimate_encoder_offsets else 0.0
    if normalised_rms > 2.0:
        warnings.append(
            f"residuals are {normalised_rms:.1f}× the assumed noise (RMS {rms_px:.2f} px with σ_px {sigma_px} px, "
            f"σ_3D {sigma_3d_m * 100:.1f} cm); σ below is scaled by that factor. Check the intrinsics, the "
            "pan/tilt readings"
            + ("" if estimate_encoder_offsets or fixed else " (or estimate encoder offsets)")
            + " and the picks, or raise --sigma-px/--sigma-3d if they are optimistic"
        )

    # ---- focal check --------------------------------------------------------------------------------
    focal = _focal_check(prob, fit, mask, sig, estimate_encoder_offsets, rms_px, focal_tolerance, focal_alpha, seed)
    if focal.flagged:
        warnings.append(f"focal length: {focal.message}")

    # ---- held-out reprojection ----------------------------------------------------------------------
    held, h_mode = _holdout(
        prob, fit, mask, sigma_px, sigma_3d_m, estimate_encoder_offsets, holdout_mode, holdout_fraction, seed
    )
    hv = held[np.isfinite(held)]
    h_rms = float(np.sqrt(np.mean(hv**2))) if hv.size else math.nan
    h_p95 = float(np.percentile(hv, 95)) if hv.size else math.nan

    residuals = tuple(
        PointResidual(
            view=prob.views[int(prob.vidx[i])].name,
            index=prob.pidx[i],
            label=prob.labels[i],
            pixel=(float(prob.uv[i, 0]), float(prob.uv[i, 1])),
            predicted=(float(pred[i, 0]), float(pred[i, 1])),
            error_px=float(err[i]),
            normalised=float(np.linalg.norm(wres[i])),
            inlier=bool(mask[i]),
        )
        for i in range(prob.n)
    )
    n_out = int(prob.n - mask.sum())
    if n_out:
        notes.append(f"{n_out} outlier(s) rejected at {outlier_k}·σ")
    if estimate_encoder_offsets:
        notes.append("pan encoder offset is not separately observable: it is contained in the mount yaw")
    if fixed:
        notes.append("fixed camera: the transform is the optical frame's pose in the reference (laser) frame")
    result = CalibrationResult(
        transform=fit.T,
        covariance=cov,
        pan_offset=0.0,
        tilt_offset=fit.tilt_offset,
        tilt_offset_sigma=tilt_sigma,
        residuals=residuals,
        rms_px=rms_px,
        normalised_rms=normalised_rms,
        holdout_rms_px=h_rms,
        holdout_p95_px=h_p95,
        holdout_mode=h_mode,
        inliers=mask,
        focal_check=focal,
        n_views=n_views,
        n_points=prob.n,
        sigma_px=sigma_px,
        sigma_3d_m=sigma_3d_m,
        start=start,
        notes=tuple(notes),
        views=_view_results(prob, fit, cov, mask, err, held),
        fixed=fixed,
        warnings=tuple(warnings),
    )

    # ---- gates on the solution: the data cannot determine the pose ------------------------------------
    st = result.sigma_translation_m
    sr = np.degrees(result.sigma_rotation_rad)
    if singular:
        return refuse(
            "degenerate geometry: the normal equations are singular (the points do not determine "
            + ("the pose and the tilt offset" if estimate_encoder_offsets else "the pose")
            + f"; condition number {corr_cond:.2g})",
            result,
        )
    if mask.sum() < min_inlier_fraction * prob.n:
        return refuse(
            f"too few inliers: only {int(mask.sum())} of {prob.n} correspondences agree with one "
            + ("camera pose" if fixed else "mount")
            + f" (< {min_inlier_fraction:.0%}); check the pairing of pixels and laser points, the intrinsics"
            + ("" if fixed else ", the pan/tilt readings")
            + ("" if fixed or estimate_encoder_offsets else " (or estimate encoder offsets)")
            + f"; {focal.message}",
            result,
        )
    # ---- optional strictness (the user asked for it) ---------------------------------------------------
    if focal.flagged and refuse_on_focal_mismatch:
        return refuse(f"inconsistent intrinsics: {focal.message}", result)
    if float(st.max()) > max_sigma_translation_m or float(sr.max()) > max_sigma_rotation_deg:
        return refuse(
            "uncertainty above the requested limit: predicted σ translation "
            f"[{', '.join(f'{v * 100:.1f}' for v in st)}] cm, "
            f"rotation [{', '.join(f'{v:.2f}' for v in sr)}]° "
            f"exceeds {max_sigma_translation_m * 100:.1f} cm / {max_sigma_rotation_deg}°; add points at other "
            "depths and over the whole image" + ("" if fixed else ", and views at other pan/tilt"),
            result,
        )
    if estimate_encoder_offsets and math.degrees(tilt_sigma) > max_sigma_rotation_deg:
        return refuse(
            f"uncertainty above the requested limit: tilt offset σ {math.degrees(tilt_sigma):.2f}° > "
            f"{max_sigma_rotation_deg}°; views at several pan angles are needed to separate it from the mount "
            "pitch",
            result,
        )
    if normalised_rms > max_normalised_rms:
        return refuse(
            f"inconsistent data: normalised RMS {normalised_rms:.2f} > {max_normalised_rms} after the refit "
            f"(RMS {rms_px:.2f} px with σ_px {sigma_px} px, σ_3D {sigma_3d_m * 100:.1f} cm); check the "
            "camera model, the pan/tilt readings"
            + ("" if estimate_encoder_offsets or fixed else " (or estimate encoder offsets)")
            + " and the picks, or raise --sigma-px/--sigma-3d if they are optimistic",
            result,
        )
    return result


def _unsolved(prob: _Problem, reason: str, sigma_px: float, sigma_3d: float) -> CalibrationResult:
    """The result of a refusal that came before any solution (``solved`` False, σ infinite)."""
    nan = math.nan
    return CalibrationResult(
        transform=Transform(),
        covariance=np.full((6, 6), np.inf),
        pan_offset=0.0,
        tilt_offset=0.0,
        tilt_offset_sigma=0.0,
        residuals=(),
        rms_px=nan,
        normalised_rms=nan,
        holdout_rms_px=nan,
        holdout_p95_px=nan,
        holdout_mode="none",
        inliers=np.zeros(prob.n, dtype=bool),
        focal_check=FocalCheck(nan, nan, nan, nan, nan, False, "not computed (no solution)"),
        n_views=len(prob.views),
        n_points=prob.n,
        sigma_px=sigma_px,
        sigma_3d_m=sigma_3d,
        start="",
        refused_reason=reason,
        fixed=prob.fixed,
        solved=False,
    )


def _replace_reason(r: CalibrationResult, reason: str) -> CalibrationResult:
    kw: dict[str, Any] = {f: getattr(r, f) for f in r.__dataclass_fields__}
    kw["refused_reason"] = reason
    return CalibrationResult(**kw)


def _skew(a: FloatArray) -> FloatArray:
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def _view_results(
    prob: _Problem, fit: _Fit, cov: FloatArray, mask: BoolArray, err: FloatArray, held: FloatArray
) -> tuple[ViewResult, ...]:
    """Per-view camera pose, its σ (the mount covariance propagated through the head), errors, labels."""
    out = []
    finite = bool(np.all(np.isfinite(cov)))
    for k, v in enumerate(prob.views):
        Tk = prob.view_pose(fit.T, fit.tilt_offset, k)
        if finite:
            # t_opt = R·h.t + t, R_opt = R·h.R with R ← exp([ω]×)·R: δt_opt = δt − [R·h.t]×·ω, δω_opt = ω
            a = Tk.t - fit.T.t
            Jv = np.block([[np.eye(3), -_skew(a)], [np.zeros((3, 3)), np.eye(3)]])
            cv = Jv @ cov @ Jv.T
            sd = np.sqrt(np.maximum(np.diag(cv), 0.0))
        else:
            sd = np.full(6, np.inf)
        sel = prob.vidx == k
        ins: list[str] = []
        outs: list[str] = []
        for i in np.flatnonzero(sel):
            name = prob.labels[i] or f"#{prob.pidx[i]}"
            (ins if mask[i] else outs).append(name)
        e_in = err[sel & mask]
        h = held[sel]
        h = h[np.isfinite(h)]
        out.append(
            ViewResult(
                name=v.name,
                T_reference_optical=Tk,
                sigma_translation_m=(float(sd[0]), float(sd[1]), float(sd[2])),
                sigma_rotation_rad=(float(sd[3]), float(sd[4]), float(sd[5])),
                rms_px=float(np.sqrt(np.mean(e_in**2))) if e_in.size else math.nan,
                holdout_rms_px=float(np.sqrt(np.mean(h**2))) if h.size else math.nan,
                inliers=tuple(ins),
                outliers=tuple(outs),
            )
        )
    return tuple(out)


def _chi2(prob: _Problem, fit: _Fit, mask: BoolArray, sig: FloatArray) -> float:
    return float(np.sum(_whitened(prob, fit, sig)[mask] ** 2))


def _focal_check(
    prob: _Problem,
    fit: _Fit,
    mask: BoolArray,
    sig: FloatArray,
    tilt: bool,
    rms_px: float,
    tolerance: float,
    alpha: float,
    seed: int,
    folds: int = 5,
) -> FocalCheck:
    """Fit a free global focal scale on the fixed-focal fit's inliers and test it (see :class:`FocalCheck`)."""
    from scipy.stats import f as f_dist

    n_in = int(mask.sum())
    p_free = 7 + int(tilt)
    dof = 2 * n_in - p_free
    if dof < 1:
        return FocalCheck(math.nan, math.nan, rms_px, math.nan, math.nan, False, "not computed (too few points)")
    ffit = _solve(prob, fit.T, fit.tilt_offset, mask, sig, estimate_tilt=tilt, estimate_focal=True, robust=False)
    chi2_fixed = _chi2(prob, fit, mask, sig)
    chi2_free = _chi2(prob, ffit, mask, sig)
    delta = max(chi2_fixed - chi2_free, 0.0)
    s = ffit.focal_scale
    scatter = max(chi2_free / dof, 1.0)  # the residuals' own variance when it exceeds the assumed one
    J = _jacobian(prob, ffit, mask, sig, tilt, True)
    try:
        var_log = float(np.linalg.inv(J.T @ J)[-1, -1]) * scatter
        sigma = s * math.sqrt(max(var_log, 0.0))
    except np.linalg.LinAlgError:
        sigma = math.inf
    f_stat = delta / max(chi2_free / dof, 1e-300)
    p_value = float(f_dist.sf(f_stat, 1, dof))
    pred = prob.project(ffit.T, ffit.tilt_offset, s)
    rms_fit = float(np.sqrt(np.mean(np.sum((pred - prob.uv)[mask] ** 2, axis=1))))
    # k-fold cross-validation on held-out points: does the free focal predict unseen points better?
    idx = np.flatnonzero(mask)
    rng = np.random.default_rng(seed + 7919)
    rng.shuffle(idx)
    k = min(folds, len(idx))
    sse_fixed = sse_free = 0.0
    n_held = 0
    for j in range(k):
        held = np.zeros(prob.n, dtype=bool)
        held[idx[j::k]] = True
        train = mask & ~held
        if 2 * int(train.sum()) <= p_free:
            continue
        a = _solve(prob, fit.T, fit.tilt_offset, train, sig, estimate_tilt=tilt, robust=False)
        b = _solve(
            prob, ffit.T, ffit.tilt_offset, train, sig, estimate_tilt=tilt, estimate_focal=True, focal0=s, robust=False
        )
        sse_fixed += _chi2(prob, a, held, sig)
        sse_free += _chi2(prob, b, held, sig)
        n_held += 2 * int(held.sum())
    cv_fixed = math.sqrt(sse_fixed / n_held) if n_held else math.nan
    cv_free = math.sqrt(sse_free / n_held) if n_held else math.nan
    dev = s - 1.0
    significant = p_value < alpha and abs(dev) > 3.0 * sigma
    flagged = bool(significant and abs(dev) > tolerance and n_held > 0 and cv_free < cv_fixed)
    msg = (
        f"focal scale {s:.3f} ± {sigma:.3f} (F = {f_stat:.1f}, p = {p_value:.2g} with 1 and {dof} dof; "
        f"held-out RMS {cv_fixed:.2f} σ with the model's focal, {cv_free:.2f} σ with the fitted one)"
    )
    if flagged:
        msg += (
            f": significant — the focal length looks {abs(dev) * 100:.1f} % too {'long' if dev < 0 else 'short'} "
            "(check the zoom/HFOV, the resolution, or measure the intrinsics: --camera-info)"
        )
    else:
        msg += ": not significant"
    return FocalCheck(s, sigma, rms_px, rms_fit, delta, flagged, msg, f_stat, p_value, dof, cv_fixed, cv_free)


def _holdout(
    prob: _Problem,
    fit: _Fit,
    mask: BoolArray,
    sigma_px: float,
    sigma_3d: float,
    tilt: bool,
    mode: HoldoutMode,
    fraction: float,
    seed: int,
) -> tuple[FloatArray, str]:
    """Cross-validated reprojection error (px) of every inlier point from a fit that did not use it (NaN for
    points never held out), and the mode used."""
    held_err = np.full(prob.n, np.nan)
    if mode == "none":
        return held_err, "none"
    n_views_used = len(np.unique(prob.vidx[mask]))
    if mode == "auto":
        mode = "views" if n_views_used >= 3 else "points"
    folds: list[BoolArray] = []
    if mode == "views":
        folds = [(prob.vidx == k) & mask for k in np.unique(prob.vidx[mask])]
    else:
        idx = np.flatnonzero(mask)
        rng = np.random.default_rng(seed)
        rng.shuffle(idx)
        k = max(2, round(1.0 / max(min(fraction, 0.5), 1e-3)))
        for f in range(k):
            m = np.zeros(prob.n, dtype=bool)
            m[idx[f::k]] = True
            folds.append(m)
    sig = prob.sigmas(fit.T, fit.tilt_offset, sigma_px, sigma_3d)
    for held in folds:
        train = mask & ~held
        if train.sum() < 6 or not held.any():
            continue
        if prob.fixed is False and len(np.unique(prob.vidx[train])) == 0:
            continue
        cv_fit = _solve(prob, fit.T, fit.tilt_offset, train, sig, estimate_tilt=tilt, robust=False)
        pred = prob.project(cv_fit.T, cv_fit.tilt_offset)
        held_err[held] = np.linalg.norm(pred[held] - prob.uv[held], axis=1)
    return held_err, mode


def rotation_error_deg(a: Transform, b: Transform) -> float:
    """Angle (deg) of ``a.R·b.Rᵀ``."""
    return math.degrees(rotation_angle(a.R @ b.R.T))


def describe(result: CalibrationResult) -> dict[str, Any]:
    """Compact summary (xyz m, REP-103 rpy deg, σ per axis) for logs and the CLI."""
    x, y, z, r, p, yw = result.xyz_rpy()
    return {
        "xyz_m": [x, y, z],
        "rpy_deg": [math.degrees(v) for v in (r, p, yw)],
        "sigma_xyz_m": result.sigma_translation_m.tolist(),
        "sigma_rot_deg": np.degrees(result.sigma_rotation_rad).tolist(),
        "tilt_offset_deg": math.degrees(result.tilt_offset),
        "rms_px": result.rms_px,
        "holdout_rms_px": result.holdout_rms_px,
        "holdout_p95_px": result.holdout_p95_px,
        "inliers": f"{result.n_inliers}/{result.n_points}",
    }
