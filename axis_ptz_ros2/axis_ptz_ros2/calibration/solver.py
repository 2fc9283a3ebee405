"""Extrinsic calibration of the PTZ base against the laser frame from picked 2-D/3-D pairs (ROS-free).

Model (geometry-and-calibration.md §1, §6; thesis §6.4)::

    T_base_opt(p_k, t_k) = T_base_ptz · head(p_k + pan_offset, t_k + tilt_offset)
    u_ki = π(K(z_k), T_base_opt(p_k, t_k)⁻¹ · X_i)

with ``head = PtzKinematics.optical_in_ptz_base`` and ``K(z)``, ``π`` from ``CameraModel.camera_info_at``: the
measured camera_info (K and lens distortion; principal point and distortion kept, focal length scaled with the
zoom curve) or the nominal zoom curve. Pixels are the raw ones the user clicked; the projection includes the
distortion. The unknowns are ``T_base_ptz`` (6 DoF: translation in metres and a rotation vector ``ω`` with
``R = exp([ω]×)·R₀`` around the current estimate ``R₀``, i.e. a rotation about the *parent* (base_link) axes)
and optionally the tilt encoder offset. For a fixed camera (``fixed=True``) the head is the identity and the
unknown is ``T_reference_optical``.

The pan encoder offset is *not* separately observable: ``head(p + δ) = Rz(δ)·head(p)`` exactly (the pan axis
is the ptz_base z axis and the tilt-axis height is on it), so any pan offset is absorbed, without loss, into
the yaw of ``T_base_ptz``; ``pan_offset`` is therefore reported as 0 and the mount's yaw carries it.

Pipeline (:func:`calibrate`):

1. Check the input: enough points (≥ ``min_points`` in total, a view with ≥ 4 for PnP), no identical rows,
   not a single camera pose of a nearly coplanar point set, enough angular spread of the observed rays.
2. Per-view PnP (SQPnP, EPnP, iterative; IPPE for planar sets) on undistorted pixels; each camera pose gives a
   ``T_base_ptz`` candidate through the known head pose. Multi-start from the candidates and their robust
   average.
3. Joint robust refinement over all views (``scipy.optimize.least_squares``, TRF with a soft-L1 loss on
   residuals whitened by ``σ_i² = σ_px² + (f·σ_3D/Z_i)²``), outlier rejection at ``k·σ_i``, and a final
   non-robust Levenberg–Marquardt refit on the inliers (iterated until the inlier set is stable).
4. Covariance ``Σ = (JᵀWJ)⁻¹`` at the optimum, inflated by ``covariance_inflation`` (on σ) and by the
   normalised RMS when it exceeds 1, reported as 6×6 (x, y, z, rotX, rotY, rotZ). Refusal only when the data
   cannot determine the pose (singular normal equations, too few inliers); limits on σ, on the normalised RMS
   and on the focal check only when the caller sets them.
5. Diagnostics (:mod:`~axis_ptz_ros2.calibration.diagnostics`): the focal-length check (cross-validated),
   held-out reprojection error (leave-one-view-out with ≥ 3 views, else k random point folds), per-view poses.

The result, the refusal and the input error are in :mod:`~axis_ptz_ros2.calibration.result`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from axis_ptz_ros2.calibration.correspondences import View
from axis_ptz_ros2.calibration.diagnostics import (
    FocalCheck,
    HoldoutMode,
    focal_check,
    holdout_errors,
    view_results,
)
from axis_ptz_ros2.calibration.problem import (
    Fit,
    Problem,
    angular_spread_deg,
    duplicate_rows,
    jacobian,
    planarity_ratio,
    pnp_points,
    pnp_view,
    robust_average,
    rotation_angle,
    solve,
    whitened,
)
from axis_ptz_ros2.calibration.result import (
    CalibrationInputError,
    CalibrationRefused,
    CalibrationResult,
    PointResidual,
)
from axis_ptz_ros2.config import CameraModel
from axis_ptz_ros2.transforms import Transform

__all__ = ["calibrate", "rotation_error_deg"]


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
    check_focal: bool = True,
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
    ``max_normalised_rms`` / ``refuse_on_focal_mismatch`` make it stricter. ``check_focal=False`` skips the
    focal-length diagnostic (ten robust refits; for batch studies). ``source`` (the file name) is
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
    prob = Problem(views, camera_model, fixed)

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
        c = pnp_points(prob, np.ones(prob.n, dtype=bool), 0, planar)
        if c is not None:
            cands.append(("pnp:all", c))
    for k in range(n_views):
        if per_view[k] >= 4:
            c = pnp_view(prob, k, planar)
            if c is not None:
                cands.append((f"pnp:{prob.views[k].name}", c))
    if not cands:
        return refuse("initialisation failed: PnP found no camera pose in any view")
    if len(cands) > 1:
        cands.append(("robust-average", robust_average([c for _, c in cands])))

    all_mask = np.ones(prob.n, dtype=bool)

    def robust_cost(T: Transform) -> float:
        sig = prob.sigmas(T, 0.0, sigma_px, sigma_3d_m)
        r = np.linalg.norm(whitened(prob, Fit(T, 0.0, 1.0, 0.0), sig), axis=1)
        return float(np.sum(np.sqrt(1.0 + (r / 2.0) ** 2) - 1.0))

    ranked = sorted(cands, key=lambda c: robust_cost(c[1]))[: max(1, n_starts)]
    best: tuple[str, Fit] | None = None
    for name, T0 in ranked:
        sig = prob.sigmas(T0, 0.0, sigma_px, sigma_3d_m)
        fit = solve(prob, T0, 0.0, all_mask, sig, estimate_tilt=False, robust=robust)
        if estimate_encoder_offsets:
            sig = prob.sigmas(fit.T, 0.0, sigma_px, sigma_3d_m)
            fit = solve(prob, fit.T, 0.0, all_mask, sig, estimate_tilt=True, robust=robust)
        if best is None or fit.cost < best[1].cost:
            best = (name, fit)
    assert best is not None
    start, fit = best

    # ---- outlier rejection and final non-robust refit --------------------------------------------------
    mask = all_mask.copy()
    for _ in range(4):
        sig = prob.sigmas(fit.T, fit.tilt_offset, sigma_px, sigma_3d_m)
        r = np.linalg.norm(whitened(prob, fit, sig), axis=1)
        new_mask = r <= outlier_k if robust else all_mask.copy()
        if new_mask.sum() < min_points:
            new_mask = r <= np.sort(r)[min(min_points, prob.n) - 1]
        changed = not np.array_equal(new_mask, mask)
        mask = new_mask
        fit = solve(prob, fit.T, fit.tilt_offset, mask, sig, estimate_tilt=estimate_encoder_offsets, robust=False)
        if not changed:
            break
    sig = prob.sigmas(fit.T, fit.tilt_offset, sigma_px, sigma_3d_m)
    wres = whitened(prob, fit, sig)
    pred = prob.project(fit.T, fit.tilt_offset)
    err = np.linalg.norm(pred - prob.uv, axis=1)
    rms_px = float(np.sqrt(np.mean(err[mask] ** 2)))
    n_par = 6 + int(estimate_encoder_offsets)
    dof = max(2 * int(mask.sum()) - n_par, 1)
    normalised_rms = float(np.sqrt(np.sum(wres[mask] ** 2) / dof))

    # ---- covariance ---------------------------------------------------------------------------------
    J = jacobian(prob, fit, mask, sig, estimate_encoder_offsets, False)
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
    if check_focal:
        focal = focal_check(
            prob,
            fit,
            mask,
            sig,
            estimate_encoder_offsets,
            rms_px,
            focal_tolerance,
            focal_alpha,
            seed,
            outlier_k=outlier_k,
        )
    else:
        focal = FocalCheck(math.nan, math.nan, rms_px, math.nan, math.nan, False, "not computed (check_focal=False)")
    if focal.flagged:
        warnings.append(f"focal length: {focal.message}")

    # ---- held-out reprojection ----------------------------------------------------------------------
    held, h_mode = holdout_errors(
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
        views=view_results(prob, fit, cov, mask, err, held),
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


def _unsolved(prob: Problem, reason: str, sigma_px: float, sigma_3d: float) -> CalibrationResult:
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


def rotation_error_deg(a: Transform, b: Transform) -> float:
    """Angle (deg) of ``a.R·b.Rᵀ``."""
    return math.degrees(rotation_angle(a.R @ b.R.T))
