"""Configuration files: the camera model (limits, optics, sign convention) and the robot mount (ROS-free).

Formats (YAML, versioned by a ``format`` key):

* ``axis_ptz_ros2/camera_model/v1`` — ``config/axis214.yaml``: ``convention`` (pan_direction, mount),
  ``zoom`` (a :class:`~axis_ptz_ros2.geometry.ZoomModel`), ``head`` (h_tilt, d_opt in metres), ``limits``
  (fallback limits in VAPIX degrees/units when the camera cannot report them), ``max_speed`` (deg/s).
* ``axis_ptz_ros2/mount/v1`` — ``config/mount.yaml``: the fixed ``parent_frame → child_frame`` transform
  (``xyz`` metres, ``rpy`` radians, REP-103), optional pan/tilt encoder offsets (rad) and a 6×6 covariance
  (x, y, z, rotX, rotY, rotZ). Written by ``axis_calibrate``, loaded by the PTZ node.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from axis_ptz_ros2.geometry import (
    AXIS_214_ZOOM,
    Mount,
    PanDirection,
    PtzKinematics,
    Transform,
    VapixConvention,
    ZoomModel,
)

CAMERA_MODEL_FORMAT = "axis_ptz_ros2/camera_model/v1"
MOUNT_FORMAT = "axis_ptz_ros2/mount/v1"
ROBOT_FORMAT = "axis_ptz_ros2/robot/v1"

CONFIG_DIR = Path(__file__).resolve().parent.parent / "config"


def _share_config_dir() -> Path | None:
    """``share/axis_ptz_ros2/config`` of a colcon/ament install, if this package is installed that way."""
    try:
        from ament_index_python.packages import PackageNotFoundError, get_package_share_directory
    except ImportError:
        return None
    try:
        return Path(get_package_share_directory("axis_ptz_ros2")) / "config"
    except (PackageNotFoundError, ValueError, LookupError, OSError):  # OSError: no AMENT_PREFIX_PATH
        return None


def default_config_path(name: str) -> Path:
    """Path of a file in the repository's ``config/`` folder, or the installed ``share/axis_ptz_ros2/config``."""
    candidates = [CONFIG_DIR / name]
    share = _share_config_dir()
    if share is not None:
        candidates.append(share / name)
    for c in candidates:
        if c.exists():
            return c
    return candidates[0]


@dataclass(frozen=True, slots=True)
class FallbackLimits:
    """Limits in VAPIX units, used only when the camera does not report them."""

    min_pan_deg: float = -170.0
    max_pan_deg: float = 170.0
    min_tilt_deg: float = -30.0
    max_tilt_deg: float = 90.0
    min_zoom: int = 1
    max_zoom: int = 9999


@dataclass(frozen=True, slots=True)
class CameraModel:
    """Everything about a camera model that is not read from the device."""

    name: str = "AXIS 214 PTZ"
    convention: VapixConvention = field(default_factory=VapixConvention)
    zoom: ZoomModel = AXIS_214_ZOOM
    head: PtzKinematics = field(default_factory=PtzKinematics)
    limits: FallbackLimits = field(default_factory=FallbackLimits)
    max_pan_speed_dps: float = 100.0
    max_tilt_speed_dps: float = 90.0


def camera_model_from_dict(d: dict[str, Any]) -> CameraModel:
    """Parse a camera-model mapping (see module docstring)."""
    fmt = d.get("format", CAMERA_MODEL_FORMAT)
    if fmt != CAMERA_MODEL_FORMAT:
        raise ValueError(f"unsupported camera model format {fmt!r}, expected {CAMERA_MODEL_FORMAT!r}")
    conv = d.get("convention", {})
    head = d.get("head", {})
    speed = d.get("max_speed", {})
    return CameraModel(
        name=str(d.get("name", "AXIS 214 PTZ")),
        convention=VapixConvention(
            PanDirection(conv.get("pan_direction", "cw")), Mount(conv.get("mount", "upright"))
        ),
        zoom=ZoomModel.from_dict(d.get("zoom", {})),
        head=PtzKinematics(
            h_tilt=float(head.get("h_tilt", 0.0687)),
            d_opt=tuple(float(v) for v in head.get("d_opt", (0.0, 0.0, 0.0))),  # type: ignore[arg-type]
        ),
        limits=FallbackLimits(**d.get("limits", {})),
        max_pan_speed_dps=float(speed.get("pan_dps", 100.0)),
        max_tilt_speed_dps=float(speed.get("tilt_dps", 90.0)),
    )


def load_camera_model(path: str | Path | None = None) -> CameraModel:
    """Load ``config/axis214.yaml`` (default) or another camera-model file."""
    p = Path(path) if path else default_config_path("axis214.yaml")
    with open(p, encoding="utf-8") as f:
        return camera_model_from_dict(yaml.safe_load(f) or {})


@dataclass(frozen=True, slots=True)
class MountConfig:
    """The fixed transform ``parent_frame → child_frame`` of the PTZ base, with optional calibration data."""

    transform: Transform = field(
        default_factory=lambda: Transform.from_xyz_rpy(-0.214, -0.044, 0.455, 0, 0, 0)
    )
    parent_frame: str = "base_link"
    child_frame: str = "axis_ptz_base"
    pan_offset: float = 0.0  # rad, added to the camera's pan reading (REP-103)
    tilt_offset: float = 0.0  # rad
    covariance: tuple[float, ...] | None = None  # 36 values, row-major, (x, y, z, rotX, rotY, rotZ)
    comment: str = ""

    def to_dict(self) -> dict[str, Any]:
        """Serialisable mapping in the ``mount/v1`` format."""
        x, y, z, r, p, yw = self.transform.xyz_rpy()
        out: dict[str, Any] = {
            "format": MOUNT_FORMAT,
            "parent_frame": self.parent_frame,
            "child_frame": self.child_frame,
            "xyz": [round(x, 6), round(y, 6), round(z, 6)],
            "rpy": [round(r, 8), round(p, 8), round(yw, 8)],
            "rpy_deg": [round(math.degrees(a), 5) for a in (r, p, yw)],
            "encoder_offsets": {"pan": float(self.pan_offset), "tilt": float(self.tilt_offset)},
        }
        if self.covariance is not None:
            out["covariance"] = [float(v) for v in self.covariance]
        if self.comment:
            out["comment"] = self.comment
        return out


def mount_from_dict(d: dict[str, Any]) -> MountConfig:
    """Parse a ``mount/v1`` mapping; ``rpy`` in radians wins over the informative ``rpy_deg``."""
    fmt = d.get("format", MOUNT_FORMAT)
    if fmt != MOUNT_FORMAT:
        raise ValueError(f"unsupported mount format {fmt!r}, expected {MOUNT_FORMAT!r}")
    xyz = [float(v) for v in d.get("xyz", (-0.214, -0.044, 0.455))]
    if "rpy" in d:
        rpy = [float(v) for v in d["rpy"]]
    else:
        rpy = [math.radians(float(v)) for v in d.get("rpy_deg", (0.0, 0.0, 0.0))]
    if len(xyz) != 3 or len(rpy) != 3:
        raise ValueError("mount xyz and rpy need three values each")
    cov = d.get("covariance")
    if cov is not None and len(cov) != 36:
        raise ValueError("mount covariance needs 36 values (6x6 row-major)")
    off = d.get("encoder_offsets", {}) or {}
    return MountConfig(
        transform=Transform.from_xyz_rpy(*xyz, *rpy),
        parent_frame=str(d.get("parent_frame", "base_link")),
        child_frame=str(d.get("child_frame", "axis_ptz_base")),
        pan_offset=float(off.get("pan", 0.0)),
        tilt_offset=float(off.get("tilt", 0.0)),
        covariance=tuple(float(v) for v in cov) if cov is not None else None,
        comment=str(d.get("comment", "")),
    )


def load_mount(path: str | Path | None = None) -> MountConfig:
    """Load ``config/mount.yaml`` (default) or another mount file."""
    p = Path(path) if path else default_config_path("mount.yaml")
    with open(p, encoding="utf-8") as f:
        return mount_from_dict(yaml.safe_load(f) or {})


def save_mount(mount: MountConfig, path: str | Path) -> None:
    """Write a mount file the PTZ node can load."""
    with open(path, "w", encoding="utf-8") as f:
        f.write("# base_link -> PTZ base transform (REP-103: metres, radians). Written by axis_ptz_ros2.\n")
        yaml.safe_dump(mount.to_dict(), f, sort_keys=False)


def covariance_matrix(mount: MountConfig) -> np.ndarray[Any, np.dtype[np.float64]] | None:
    """The mount covariance as a 6×6 array, if present."""
    if mount.covariance is None:
        return None
    return np.array(mount.covariance, dtype=np.float64).reshape(6, 6)


@dataclass(frozen=True, slots=True)
class SensorPose:
    """A sensor's frame name and its pose ``T_base_sensor``."""

    frame: str
    pose: Transform


@dataclass(frozen=True, slots=True)
class RobotConfig:
    """Frames of the robot used by the operator tools and simulated sensors (``robot/v1``)."""

    base_frame: str = "base_link"
    panorama: SensorPose = field(
        default_factory=lambda: SensorPose(
            "panorama_link", Transform.from_xyz_rpy(0.216, -0.044, 0.75, 0, 0, 0)
        )
    )
    laser: SensorPose = field(
        default_factory=lambda: SensorPose("laser_link", Transform.from_xyz_rpy(0.25, 0.0, 0.40, 0, 0, 0))
    )
    ground_z: float = 0.0
    default_range: float = 10.0
    depth_cone_deg: float = 1.0


def _sensor(d: dict[str, Any], default: SensorPose) -> SensorPose:
    if not d:
        return default
    xyz = [float(v) for v in d.get("xyz", (0.0, 0.0, 0.0))]
    rpy = [float(v) for v in d.get("rpy", (0.0, 0.0, 0.0))]
    return SensorPose(str(d.get("frame", default.frame)), Transform.from_xyz_rpy(*xyz, *rpy))


def robot_from_dict(d: dict[str, Any]) -> RobotConfig:
    """Parse a ``robot/v1`` mapping."""
    fmt = d.get("format", ROBOT_FORMAT)
    if fmt != ROBOT_FORMAT:
        raise ValueError(f"unsupported robot format {fmt!r}, expected {ROBOT_FORMAT!r}")
    base = RobotConfig()
    return RobotConfig(
        base_frame=str(d.get("base_frame", base.base_frame)),
        panorama=_sensor(d.get("panorama", {}), base.panorama),
        laser=_sensor(d.get("laser", {}), base.laser),
        ground_z=float(d.get("ground_z", base.ground_z)),
        default_range=float(d.get("default_range", base.default_range)),
        depth_cone_deg=float(d.get("depth_cone_deg", base.depth_cone_deg)),
    )


def load_robot(path: str | Path | None = None) -> RobotConfig:
    """Load ``config/robot.yaml`` (default) or another robot file."""
    p = Path(path) if path else default_config_path("robot.yaml")
    with open(p, encoding="utf-8") as f:
        return robot_from_dict(yaml.safe_load(f) or {})
