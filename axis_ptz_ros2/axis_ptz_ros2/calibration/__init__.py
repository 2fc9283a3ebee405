"""Extrinsic calibration of the PTZ base against the laser frame (ROS-free; thesis §6.4, geometry §6).

* :mod:`~axis_ptz_ros2.calibration.correspondences` — the ``axis_ptz_ros2/correspondences/v1`` file format
  (:func:`load_correspondences`, :func:`save_correspondences`, :func:`append_view`).
* :mod:`~axis_ptz_ros2.calibration.solver` — :func:`calibrate` → :class:`CalibrationResult` or
  :class:`CalibrationRefused` (both in :mod:`~axis_ptz_ros2.calibration.result`; imported lazily: they pull in
  OpenCV and SciPy); the least-squares model is in
  :mod:`~axis_ptz_ros2.calibration.problem`, the focal check / held-out errors / per-view poses in
  :mod:`~axis_ptz_ros2.calibration.diagnostics`, the JSON report in :mod:`~axis_ptz_ros2.calibration.report`.
* :mod:`~axis_ptz_ros2.calibration.synthetic` — seeded scenes with ground truth.
* :mod:`~axis_ptz_ros2.calibration.cli` — the ``axis_calibrate`` console script.
"""

from __future__ import annotations

import importlib
from typing import Any

from axis_ptz_ros2.calibration.correspondences import (
    CORRESPONDENCES_FORMAT,
    Correspondence,
    CorrespondenceError,
    CorrespondenceSet,
    View,
    append_view,
    load_correspondences,
    save_correspondences,
)

#: name → the module that defines it (imported on first access)
_LAZY = {
    "calibrate": "axis_ptz_ros2.calibration.solver",
    "CalibrationResult": "axis_ptz_ros2.calibration.result",
    "CalibrationRefused": "axis_ptz_ros2.calibration.result",
    "PointResidual": "axis_ptz_ros2.calibration.result",
    "FocalCheck": "axis_ptz_ros2.calibration.diagnostics",
}

__all__ = [
    "CORRESPONDENCES_FORMAT",
    "CalibrationRefused",
    "CalibrationResult",
    "Correspondence",
    "CorrespondenceError",
    "CorrespondenceSet",
    "FocalCheck",
    "PointResidual",
    "View",
    "append_view",
    "calibrate",
    "load_correspondences",
    "save_correspondences",
]


def __getattr__(name: str) -> Any:
    """Lazy access to the solver's public names."""
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
