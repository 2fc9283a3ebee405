"""Machine-readable calibration report (``axis_calibrate solve --report FILE.json``; ROS-free).

Format ``axis_ptz_ros2/calibration_report/v1`` (JSON; non-finite numbers are written as ``null``)::

    {
      "format": "axis_ptz_ros2/calibration_report/v1",
      "refused": null,                    # or the reason (string) when the data cannot determine the pose
      "solved": true,                     # false when the refusal came before any solution
      "mode": "ptz",                      # "ptz" (T_base_ptz solved) or "fixed" (T_reference_optical solved)
      "transform": {"parent": "base_link", "child": "axis_ptz_base", "translation": [x, y, z],   # m
                    "quaternion_xyzw": [qx, qy, qz, qw], "rpy_deg": [r, p, y],
                    "sigma_translation_m": [sx, sy, sz], "sigma_rotation_deg": [rx, ry, rz],  # about parent axes
                    "covariance": [36 values, row-major, x y z m, rotX rotY rotZ rad]},
      "tilt_offset_deg": 0.0, "tilt_offset_sigma_deg": 0.0,
      "rms_px": 0.9, "normalised_rms": 1.0, "n_points": 40, "n_inliers": 39,
      "holdout": {"mode": "views", "rms_px": 1.2, "p95_px": 2.3},
      "focal_check": {"scale": 1.0, "sigma": 0.01, "f_stat": 0.3, "p_value": 0.6, "dof": 71,
                      "cv_rms_model": 1.0, "cv_rms_fitted": 1.0, "cv_z": 0.4, "significant": false,
                      "message": "..."},
      "views": [{"name": "view0",
                 "T_reference_optical": {"translation": [x, y, z], "quaternion_xyzw": [qx, qy, qz, qw]},
                 "sigma_translation_m": [..], "sigma_rotation_deg": [..],
                 "rms_px": 0.8, "holdout_rms_px": 1.1,
                 "inliers": ["p0", ...], "outliers": ["p5"]}],
      "warnings": [...], "notes": [...], "input": {...}
    }

``T_reference_optical`` is the optical frame (x right, y down, z forward) of that view in the reference
frame the 3-D points are given in (the laser / ``base_link`` frame). Pixel errors are in raw image pixels.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from axis_ptz_ros2.calibration.result import CalibrationResult
from axis_ptz_ros2.transforms import Transform, matrix_to_quaternion

REPORT_FORMAT = "axis_ptz_ros2/calibration_report/v1"


def _num(x: float) -> float | None:
    v = float(x)
    return v if math.isfinite(v) else None


def _nums(xs: Any) -> list[float | None]:
    return [_num(v) for v in np.asarray(xs, dtype=np.float64).reshape(-1)]


def _pose(T: Transform) -> dict[str, Any]:
    return {"translation": _nums(T.t), "quaternion_xyzw": [float(v) for v in matrix_to_quaternion(T.R)]}


def report_dict(
    result: CalibrationResult,
    *,
    parent_frame: str = "base_link",
    child_frame: str = "axis_ptz_base",
    inputs: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """The report mapping of a result (refused or not)."""
    r = result
    x, y, z, roll, pitch, yaw = r.transform.xyz_rpy()
    fc = r.focal_check
    out: dict[str, Any] = {
        "format": REPORT_FORMAT,
        "refused": r.refused_reason,
        "solved": r.solved,
        "mode": "fixed" if r.fixed else "ptz",
        "transform": None,
        "tilt_offset_deg": _num(math.degrees(r.tilt_offset)),
        "tilt_offset_sigma_deg": _num(math.degrees(r.tilt_offset_sigma)),
        "rms_px": _num(r.rms_px),
        "normalised_rms": _num(r.normalised_rms),
        "n_points": r.n_points,
        "n_inliers": r.n_inliers,
        "holdout": {"mode": r.holdout_mode, "rms_px": _num(r.holdout_rms_px), "p95_px": _num(r.holdout_p95_px)},
        "focal_check": {
            "scale": _num(fc.scale),
            "sigma": _num(fc.sigma),
            "f_stat": _num(fc.f_stat),
            "p_value": _num(fc.p_value),
            "dof": fc.dof,
            "cv_rms_model": _num(fc.cv_rms_model),
            "cv_rms_fitted": _num(fc.cv_rms_fitted),
            "cv_z": _num(fc.cv_z),
            "significant": fc.flagged,
            "message": fc.message,
        },
        "views": [
            {
                "name": v.name,
                "T_reference_optical": _pose(v.T_reference_optical),
                "sigma_translation_m": _nums(v.sigma_translation_m),
                "sigma_rotation_deg": _nums(np.degrees(v.sigma_rotation_rad)),
                "rms_px": _num(v.rms_px),
                "holdout_rms_px": _num(v.holdout_rms_px),
                "inliers": list(v.inliers),
                "outliers": list(v.outliers),
            }
            for v in r.views
        ],
        "warnings": list(r.warnings),
        "notes": list(r.notes),
        "input": {
            "sigma_px": r.sigma_px,
            "sigma_3d_m": r.sigma_3d_m,
            "n_views": r.n_views,
            **(inputs or {}),
        },
    }
    if r.solved:
        out["transform"] = {
            "parent": parent_frame,
            "child": child_frame,
            **_pose(r.transform),
            "rpy_deg": [math.degrees(v) for v in (roll, pitch, yaw)],
            "xyz": [x, y, z],
            "sigma_translation_m": _nums(r.sigma_translation_m),
            "sigma_rotation_deg": _nums(np.degrees(r.sigma_rotation_rad)),
            "covariance": _nums(r.covariance),
        }
    return out


def write_report(report: dict[str, Any], path: str | Path) -> None:
    """Write the report as strict JSON (atomically replaces ``path``)."""
    p = Path(path)
    tmp = p.with_name(p.name + ".tmp")
    tmp.write_text(json.dumps(report, indent=2, ensure_ascii=False, allow_nan=False) + "\n", encoding="utf-8")
    tmp.replace(p)
