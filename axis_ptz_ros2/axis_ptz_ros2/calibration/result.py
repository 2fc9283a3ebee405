"""What the extrinsic calibration gives (ROS-free): :class:`CalibrationResult` (the transform, its covariance, the
residuals and diagnostics), the refusal :class:`CalibrationRefused`, the input error :class:`CalibrationInputError`,
and :func:`describe` (a compact summary). Computed by :func:`axis_ptz_ros2.calibration.solver.calibrate`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from axis_ptz_ros2.calibration.diagnostics import FocalCheck, ViewResult
from axis_ptz_ros2.config import MountConfig
from axis_ptz_ros2.transforms import Transform

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

__all__ = [
    "CalibrationInputError",
    "CalibrationRefused",
    "CalibrationResult",
    "PointResidual",
    "describe",
]


class CalibrationRefused(Exception):  # noqa: N818  (public API name)
    """The data cannot give a trustworthy mount; ``reason`` says why, ``result`` holds the diagnostics if a
    solution was computed (``result.refused_reason == reason``)."""

    def __init__(self, reason: str, result: CalibrationResult | None = None) -> None:
        super().__init__(reason)
        self.reason = reason
        self.result = result


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
class CalibrationResult:
    """Outcome of :func:`~axis_ptz_ros2.calibration.solver.calibrate`. ``transform`` is ``T_base_ptz`` (ptz_base in
    the base/laser frame) or, for a fixed camera, ``T_reference_optical``. ``solved`` is False when the refusal came
    before any solution (then the transform is the identity and σ infinite)."""

    transform: Transform
    covariance: FloatArray  # 6×6 (x, y, z m; rotX, rotY, rotZ rad about the parent axes), inflated
    pan_offset: float  # rad; always 0 (absorbed into the mount yaw, see the solver's module docstring)
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


class CalibrationInputError(ValueError):
    """The views are not usable as given (e.g. a PTZ solve with views that have no pan/tilt)."""


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
