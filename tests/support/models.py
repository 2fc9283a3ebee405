"""Camera models for tests, read from their files through the project's loader (a camera's facts live only in its
``config/<model>.yaml``; the code holds no camera's figures)."""

from __future__ import annotations

from axis_ptz_ros2.config import CONFIG_DIR, CameraModel, load_camera_model
from axis_ptz_ros2.optics import ZoomModel

#: config/axis214.yaml: the Axis 214 of the thesis, the simulated camera's default persona
AXIS_214: CameraModel = load_camera_model(CONFIG_DIR / "axis214.yaml")
#: … its zoom model (zoom units ↔ magnification ↔ field of view, pixel aspect)
AXIS_214_ZOOM: ZoomModel = AXIS_214.zoom
