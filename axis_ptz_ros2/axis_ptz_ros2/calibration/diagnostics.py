"""Diagnostics of a calibration (ROS-free): the focal-length check, held-out reprojection errors and the
per-view poses with their uncertainty. Used by :func:`axis_ptz_ros2.calibration.solver.calibrate`."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
import numpy.typing as npt

from axis_ptz_ros2.calibration.problem import Fit, Problem, chi2, jacobian, skew, solve, whitened
from axis_ptz_ros2.transforms import Transform

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

HoldoutMode = Literal["auto", "views", "points", "none"]


@dataclass(frozen=True, slots=True)
class FocalCheck:
    """Diagnostic fit of a global focal-length scale ``s`` (fx, fy × s in every view).

    Significance comes from k-fold cross-validation over all points (outliers are down-weighted inside each
    training fold only, so the held-out score has no selection bias), not from a test on inliers the
    check picked itself; see :func:`focal_check`. The F-test of the nested fits on the fixed-focal fit's
    inliers is reported beside it.
    """

    scale: float  # best-fit s (1 = the camera model is right); NaN when not computed
    sigma: float  # 1σ of s
    rms_px_model: float  # inlier RMS (px) with the camera model's focal length
    rms_px_fitted: float  # RMS (px) with the fitted scale over the points its fit kept
    delta_chi2: float  # χ² drop from freeing the scale on the fixed-focal fit's inliers
    flagged: bool  # significant (see above)
    message: str
    f_stat: float = math.nan  # F = Δχ² / (χ²_free / dof)
    p_value: float = math.nan  # P(F(1, dof) ≥ f_stat)
    dof: int = 0
    cv_rms_model: float = math.nan  # k-fold held-out whitened RMS with the model's focal length
    cv_rms_fitted: float = math.nan  # ... with a free focal scale
    cv_z: float = math.nan  # one-sided z of the paired held-out loss differences (model − free)


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


def view_results(
    prob: Problem, fit: Fit, cov: FloatArray, mask: BoolArray, err: FloatArray, held: FloatArray
) -> tuple[ViewResult, ...]:
    """Per-view camera pose, its σ (the mount covariance propagated through the head), errors, labels."""
    out = []
    finite = bool(np.all(np.isfinite(cov)))
    for k, v in enumerate(prob.views):
        Tk = prob.view_pose(fit.T, fit.tilt_offset, k)
        if finite:
            # t_opt = R·h.t + t, R_opt = R·h.R with R ← exp([ω]×)·R: δt_opt = δt − [R·h.t]×·ω, δω_opt = ω
            a = Tk.t - fit.T.t
            Jv = np.block([[np.eye(3), -skew(a)], [np.zeros((3, 3)), np.eye(3)]])
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


def focal_check(
    prob: Problem,
    fit: Fit,
    mask: BoolArray,
    sig: FloatArray,
    tilt: bool,
    rms_px: float,
    tolerance: float,
    alpha: float,
    seed: int,
    folds: int = 5,
    outlier_k: float = 3.0,
) -> FocalCheck:
    """Estimate a free global focal scale and test it without selection bias (see :class:`FocalCheck`).

    * Estimate ``s ± σ``: a robust free-focal fit on every point, then a plain refit on its inliers; σ scaled by
      the residuals' own scatter when it exceeds the assumed noise.
    * F-test of the nested plain fits (model focal vs free focal) on the inliers the *fixed-focal* fit chose,
      with 1 and ``2n − p`` degrees of freedom (reported; that selection favours the model's focal).
    * Significance: k-fold cross-validation over all points. In every fold both models are fitted robustly on
      the training points only (any outlier down-weighting happens there), and each held-out point is scored
      with its whitened error truncated at ``outlier_k`` (a gross outlier costs both models the same). The
      paired per-point differences give a one-sided z; ``flagged`` needs z above the ``alpha`` quantile, a
      deviation beyond ``tolerance`` and beyond 3σ.
    """
    from scipy.stats import f as f_dist
    from scipy.stats import norm

    n_in = int(mask.sum())
    p_free = 7 + int(tilt)
    dof = 2 * n_in - p_free
    if dof < 1 or prob.n < 2 * folds:
        return FocalCheck(math.nan, math.nan, rms_px, math.nan, math.nan, False, "not computed (too few points)")
    all_mask = np.ones(prob.n, dtype=bool)
    # -- estimate ----------------------------------------------------------------------------------------
    rfit = solve(prob, fit.T, fit.tilt_offset, all_mask, sig, estimate_tilt=tilt, estimate_focal=True, robust=True)
    r = np.linalg.norm(whitened(prob, rfit, sig), axis=1)
    emask = r <= outlier_k
    if 2 * int(emask.sum()) <= p_free:
        emask = mask
    efit = solve(
        prob,
        rfit.T,
        rfit.tilt_offset,
        emask,
        sig,
        estimate_tilt=tilt,
        estimate_focal=True,
        focal0=rfit.focal_scale,
        robust=False,
    )
    s = efit.focal_scale
    e_dof = max(2 * int(emask.sum()) - p_free, 1)
    scatter = max(chi2(prob, efit, emask, sig) / e_dof, 1.0)
    J = jacobian(prob, efit, emask, sig, tilt, True)
    try:
        sigma = s * math.sqrt(max(float(np.linalg.inv(J.T @ J)[-1, -1]) * scatter, 0.0))
    except np.linalg.LinAlgError:
        sigma = math.inf
    pred = prob.project(efit.T, efit.tilt_offset, s)
    rms_fit = float(np.sqrt(np.mean(np.sum((pred - prob.uv)[emask] ** 2, axis=1))))
    # -- F-test on the fixed-focal fit's inliers ---------------------------------------------------------
    ffit = solve(prob, fit.T, fit.tilt_offset, mask, sig, estimate_tilt=tilt, estimate_focal=True, robust=False)
    chi2_fixed = chi2(prob, fit, mask, sig)
    chi2_free = chi2(prob, ffit, mask, sig)
    delta = max(chi2_fixed - chi2_free, 0.0)
    f_stat = delta / max(chi2_free / dof, 1e-300)
    p_value = float(f_dist.sf(f_stat, 1, dof))
    # -- cross-validation over all points ----------------------------------------------------------------
    idx = np.arange(prob.n)
    rng = np.random.default_rng(seed + 7919)
    rng.shuffle(idx)
    cap = outlier_k**2
    d_all: list[FloatArray] = []
    loss_fixed: list[FloatArray] = []
    loss_free: list[FloatArray] = []
    for j in range(folds):
        held = np.zeros(prob.n, dtype=bool)
        held[idx[j::folds]] = True
        train = ~held
        a = solve(prob, fit.T, fit.tilt_offset, train, sig, estimate_tilt=tilt, robust=True)
        b = solve(
            prob, efit.T, efit.tilt_offset, train, sig, estimate_tilt=tilt, estimate_focal=True, focal0=s, robust=True
        )
        la = np.minimum(np.sum(whitened(prob, a, sig)[held] ** 2, axis=1), cap)
        lb = np.minimum(np.sum(whitened(prob, b, sig)[held] ** 2, axis=1), cap)
        loss_fixed.append(la)
        loss_free.append(lb)
        d_all.append(la - lb)
    d = np.concatenate(d_all)
    sd = float(np.std(d, ddof=1)) if len(d) > 1 else 0.0
    cv_z = float(np.mean(d)) / (sd / math.sqrt(len(d))) if sd > 0 else 0.0
    cv_fixed = float(np.sqrt(np.mean(np.concatenate(loss_fixed)) / 2.0))
    cv_free = float(np.sqrt(np.mean(np.concatenate(loss_free)) / 2.0))
    z_crit = float(norm.isf(alpha))
    dev = s - 1.0
    flagged = bool(cv_z > z_crit and abs(dev) > tolerance and abs(dev) > 3.0 * sigma)
    msg = (
        f"focal scale {s:.3f} ± {sigma:.3f} (cross-validated: held-out points predicted better with it at "
        f"z = {cv_z:.1f}, needs > {z_crit:.1f}; held-out RMS {cv_fixed:.2f} σ with the model's focal, {cv_free:.2f} σ "
        f"with the fitted one; F = {f_stat:.1f}, p = {p_value:.2g} with 1 and {dof} dof on the inliers)"
    )
    if flagged:
        msg += (
            f": significant — the focal length looks {abs(dev) * 100:.1f} % too {'long' if dev < 0 else 'short'} "
            "(check the zoom/HFOV, the resolution, or measure the intrinsics: --camera-info)"
        )
    else:
        msg += ": not significant"
    return FocalCheck(s, sigma, rms_px, rms_fit, delta, flagged, msg, f_stat, p_value, dof, cv_fixed, cv_free, cv_z)


def holdout_errors(
    prob: Problem,
    fit: Fit,
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
        cv_fit = solve(prob, fit.T, fit.tilt_offset, train, sig, estimate_tilt=tilt, robust=False)
        pred = prob.project(cv_fit.T, cv_fit.tilt_offset)
        held_err[held] = np.linalg.norm(pred[held] - prob.uv[held], axis=1)
    return held_err, mode
