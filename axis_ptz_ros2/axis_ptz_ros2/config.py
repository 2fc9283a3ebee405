"""Configuration files: the camera model (limits, optics, sign convention) and the robot mount (ROS-free).

Formats (YAML, versioned by a ``format`` key):

* ``axis_ptz_ros2/camera_model/v1`` — ``config/axis214.yaml``: ``convention`` (pan_direction, mount),
  ``zoom`` (a :class:`~axis_ptz_ros2.optics.ZoomModel`), ``head`` (h_tilt, d_opt in metres), ``limits``
  (fallback limits in VAPIX degrees/units when the camera cannot report them), ``max_speed`` (deg/s), and
  optionally ``camera_info`` — a measured calibration in the ROS camera calibration YAML format, as a path
  (relative to the model file) or inline — with ``camera_info_zoom`` (VAPIX units it was measured at; default
  the wide end). ``name``, ``zoom`` (at least ``hfov_wide_deg`` and ``max_magnification``), ``head``, ``limits``
  and ``max_speed`` are required: the code holds no camera's figures, and a file without one of them is refused
  naming the file and the key. Unknown fields, duplicate keys and broken YAML are refused with the file and
  field named.
* ``axis_ptz_ros2/mount/v1`` — ``config/mount.yaml``: the fixed ``parent_frame → child_frame`` transform
  (``xyz`` metres, ``rpy`` radians, REP-103), optional pan/tilt encoder offsets (rad) and a 6×6 covariance
  (x, y, z, rotX, rotY, rotZ). Written by ``axis_calibrate``, loaded by the PTZ node.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from axis_ptz_ros2.camera_info import (
    CameraInfoData,
    CameraInfoError,
    camera_info_from_dict,
    load_camera_info,
    nominal_camera_info,
)
from axis_ptz_ros2.geometry import Mount, PanDirection, PtzKinematics, VapixConvention
from axis_ptz_ros2.optics import ZOOM_REQUIRED, Intrinsics, ZoomModel
from axis_ptz_ros2.strict_yaml import load_strict
from axis_ptz_ros2.transforms import Transform

CAMERA_MODEL_FORMAT = "axis_ptz_ros2/camera_model/v1"
MOUNT_FORMAT = "axis_ptz_ros2/mount/v1"
ROBOT_FORMAT = "axis_ptz_ros2/robot/v1"

CONFIG_DIR = Path(__file__).resolve().parents[2] / "config"  # config/ of a source checkout


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
    """Limits in VAPIX units, used only when the camera does not report them (every field from the model file)."""

    min_pan_deg: float
    max_pan_deg: float
    min_tilt_deg: float
    max_tilt_deg: float
    min_zoom: int
    max_zoom: int


@dataclass(frozen=True, slots=True)
class CameraModel:
    """Everything about a camera model that is not read from the device.

    ``camera_info`` (optional) is a measured calibration (ROS camera calibration YAML, e.g. from the
    ``camera_calibration`` tool) taken at zoom ``camera_info_zoom``: when present it replaces the nominal
    wide-end intrinsics — principal point and distortion kept, focal length scaled with the zoom curve
    (:meth:`camera_info_at`).

    The model's facts (name, optics, head geometry, fallback limits, top speeds) have no defaults here: they come
    from its file (``config/<model>.yaml``, :func:`load_camera_model`), never from code.
    """

    name: str
    zoom: ZoomModel
    head: PtzKinematics
    limits: FallbackLimits
    max_pan_speed_dps: float
    max_tilt_speed_dps: float
    convention: VapixConvention = field(default_factory=VapixConvention)  # the documented VAPIX one
    camera_info: CameraInfoData | None = None
    camera_info_zoom: float | None = None  # zoom units of the measurement (None: the wide end, zoom.min_zoom)

    def camera_info_at(self, zoom: float, width: int, height: int) -> CameraInfoData:
        """The calibration of a ``width``×``height`` stream at ``zoom`` units: the measured one adapted
        (focal × magnification ratio, principal point and distortion kept, scaled with the image size), or
        the nominal distortion-free pinhole of the zoom curve. A stream whose aspect ratio differs from the
        measured one (another crop of the sensor) cannot be derived from it and gets the nominal values."""
        ci = self.camera_info
        if ci is None or abs(width * ci.height - height * ci.width) > 0.01 * width * ci.height:
            return nominal_camera_info(self.zoom.intrinsics(zoom, width, height))
        z0 = self.zoom.min_zoom if self.camera_info_zoom is None else self.camera_info_zoom
        m = self.zoom.magnification(zoom) / self.zoom.magnification(z0)
        return ci.adapted(width, height, m)

    def intrinsics(self, zoom: float, width: int, height: int) -> Intrinsics:
        """Pinhole K at ``zoom`` for a ``width``×``height`` stream (measured if available; see
        :meth:`camera_info_at` for the distortion that goes with it)."""
        return self.camera_info_at(zoom, width, height).intrinsics()

    def with_camera_info(self, ci: CameraInfoData | None, zoom: float | None = None) -> CameraModel:
        """A copy with another measured calibration (``None`` removes it)."""
        return replace(self, camera_info=ci, camera_info_zoom=zoom)


class CameraModelError(ValueError):
    """A camera-model file is malformed; the message names the file and the field."""


#: Allowed keys of a camera-model file (a typo is refused, not ignored). Extend when adding fields.
CAMERA_MODEL_KEYS: dict[str, set[str] | None] = {
    "format": None,
    "name": None,
    "convention": {"pan_direction", "mount"},
    "zoom": {f for f in ZoomModel.__dataclass_fields__},
    "head": {"h_tilt", "d_opt"},
    "limits": {f for f in FallbackLimits.__dataclass_fields__},
    "max_speed": {"pan_dps", "tilt_dps"},
    "camera_info": None,  # path (relative to the model file) or an inline ROS camera calibration mapping
    "camera_info_zoom": None,
    "dynamics": None,  # read by the virtual head only (config/virtual_camera.yaml)
    "products": None,  # Brand.ProdNbr / ProdShortName list for automatic selection (camera_models.py)
}


#: What a camera-model file must give (top-level key → the keys it must hold; None: a scalar). A file without one
#: is refused naming the file and the key: no camera's figures are filled in from code.
CAMERA_MODEL_REQUIRED: dict[str, tuple[str, ...] | None] = {
    "name": None,
    "zoom": ZOOM_REQUIRED,
    "head": ("h_tilt", "d_opt"),
    "limits": tuple(FallbackLimits.__dataclass_fields__),
    "max_speed": ("pan_dps", "tilt_dps"),
}
_REQUIRED_WHAT = {
    "name": "the model's name",
    "zoom": "the optics",
    "head": "the head geometry: h_tilt, d_opt in metres",
    "limits": "fallback PTZ limits in VAPIX degrees/units",
    "max_speed": "top pan/tilt speeds in deg/s",
}


def _check_required(d: dict[str, Any], source: str) -> None:
    for key, inner in CAMERA_MODEL_REQUIRED.items():
        if d.get(key) is None:
            raise CameraModelError(f"{source}: missing key '{key}' ({_REQUIRED_WHAT[key]})")
        missing = [k for k in inner or () if k not in d[key]]
        if missing:
            raise CameraModelError(f"{source}: {key}: missing key '{missing[0]}' (needs {', '.join(inner or ())})")


def _check_model_keys(d: dict[str, Any], source: str) -> None:
    unknown = sorted(str(k) for k in d if k not in CAMERA_MODEL_KEYS)
    if unknown:
        raise CameraModelError(f"{source}: unknown field(s) {unknown}; allowed: {sorted(CAMERA_MODEL_KEYS)}")
    for key, allowed in CAMERA_MODEL_KEYS.items():
        if allowed is None or key not in d or d[key] is None:
            continue
        sub = d[key]
        if not isinstance(sub, dict):
            raise CameraModelError(f"{source}: {key}: expected a mapping, got {sub!r}")
        bad = sorted(str(k) for k in sub if k not in allowed)
        if bad:
            raise CameraModelError(f"{source}: {key}.{bad[0]}: unknown field(s) {bad}; allowed: {sorted(allowed)}")


def camera_model_from_dict(
    d: dict[str, Any], source: str = "<camera model>", base_dir: Path | None = None
) -> CameraModel:
    """Parse a camera-model mapping (see module docstring); raises :class:`CameraModelError` naming the field.

    ``camera_info`` may be a path (relative to ``base_dir``, the model file's folder) or an inline mapping.
    """
    if not isinstance(d, dict):
        raise CameraModelError(f"{source}: expected a mapping, got {type(d).__name__}")
    _check_model_keys(d, source)
    fmt = d.get("format", CAMERA_MODEL_FORMAT)
    if fmt != CAMERA_MODEL_FORMAT:
        raise CameraModelError(f"{source}: unsupported camera model format {fmt!r}, expected {CAMERA_MODEL_FORMAT!r}")
    _check_required(d, source)
    conv = d.get("convention") or {}
    head = d["head"]
    speed = d["max_speed"]
    where = "convention"
    try:
        convention = VapixConvention(PanDirection(conv.get("pan_direction", "cw")), Mount(conv.get("mount", "upright")))
        where = "zoom"
        zoom = ZoomModel.from_dict(d["zoom"])
        where = "head"
        d_opt = tuple(float(v) for v in head["d_opt"])
        if len(d_opt) != 3:
            raise ValueError(f"d_opt needs three values [x, y, z] (m), got {list(d_opt)}")
        kin = PtzKinematics(h_tilt=float(head["h_tilt"]), d_opt=(d_opt[0], d_opt[1], d_opt[2]))
        where = "limits"
        limits = FallbackLimits(**d["limits"])
        where = "max_speed"
        pan_dps, tilt_dps = float(speed["pan_dps"]), float(speed["tilt_dps"])
        where = "camera_info_zoom"
        ci_zoom = d.get("camera_info_zoom")
        ci_zoom_f = None if ci_zoom is None else float(ci_zoom)
    except (TypeError, ValueError, OverflowError) as err:  # OverflowError: an integer beyond a double (fuzz tier)
        raise CameraModelError(f"{source}: {where}: {err}") from err
    ci = None
    ref = d.get("camera_info")
    try:
        if isinstance(ref, str):
            path = Path(ref).expanduser()
            if not path.is_absolute() and base_dir is not None:
                path = base_dir / path
            ci = load_camera_info(path)
        elif ref is not None:
            ci = camera_info_from_dict(ref, f"{source}: camera_info")
    except CameraInfoError as err:
        raise CameraModelError(f"{source}: camera_info: {err}") from err
    return CameraModel(
        name=str(d["name"]),
        convention=convention,
        zoom=zoom,
        head=kin,
        limits=limits,
        max_pan_speed_dps=pan_dps,
        max_tilt_speed_dps=tilt_dps,
        camera_info=ci,
        camera_info_zoom=ci_zoom_f,
    )


def load_camera_model(path: str | Path | None = None) -> CameraModel:
    """Load ``config/axis214.yaml`` (default) or another camera-model file.

    Raises :class:`CameraModelError` (a ``ValueError``) for an unreadable file, broken YAML, duplicate keys,
    unknown fields and bad values, with the file (and line, for YAML errors) in the message.
    """
    p = Path(path) if path else default_config_path("axis214.yaml")
    return camera_model_from_dict(load_strict(p, CameraModelError) or {}, str(p), p.parent)


@dataclass(frozen=True, slots=True)
class MountConfig:
    """The fixed transform ``parent_frame → child_frame`` of the PTZ base, with optional calibration data."""

    transform: Transform = field(default_factory=lambda: Transform.from_xyz_rpy(-0.214, -0.044, 0.455, 0, 0, 0))
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


class ConfigError(ValueError):
    """A mount or robot file is malformed; the message names the file and the field and what is accepted."""


def _mapping(d: Any, where: str) -> dict[str, Any]:
    if d is None:
        return {}
    if not isinstance(d, dict):
        raise ConfigError(f"{where}: expected a mapping, got {d!r}")
    return d


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ConfigError(f"{where}: expected a number, got {value!r}")
    try:
        result = float(value)
    except OverflowError:
        result = math.inf
    if not math.isfinite(result):
        raise ConfigError(f"{where}: expected a finite number, got {value!r}")
    return result


def _numbers(value: Any, n: int, where: str) -> tuple[float, ...]:
    if not isinstance(value, list | tuple) or len(value) != n:
        raise ConfigError(f"{where}: expected a list of {n} numbers, got {value!r}")
    return tuple(_number(v, f"{where}[{i}]") for i, v in enumerate(value))


def _text(value: Any, where: str) -> str:
    if not isinstance(value, str) or not value.strip():
        raise ConfigError(f"{where}: expected a non-empty string, got {value!r}")
    return value


def _check_keys(d: dict[str, Any], allowed: set[str], where: str) -> None:
    unknown = sorted(str(k) for k in d if k not in allowed)
    if unknown:
        raise ConfigError(f"{where}: unknown field(s) {unknown}; allowed: {sorted(allowed)}")


_MOUNT_KEYS = {
    "format",
    "parent_frame",
    "child_frame",
    "xyz",
    "rpy",
    "rpy_deg",
    "encoder_offsets",
    "covariance",
    "comment",
}


def mount_from_dict(d: dict[str, Any], source: str = "<mount>") -> MountConfig:
    """Parse a ``mount/v1`` mapping; ``rpy`` in radians wins over the informative ``rpy_deg``.

    Raises :class:`ConfigError` naming the field for anything else than the documented shape.
    """
    d = _mapping(d, source)
    _check_keys(d, _MOUNT_KEYS, source)
    fmt = d.get("format", MOUNT_FORMAT)
    if fmt != MOUNT_FORMAT:
        raise ConfigError(f"{source}: unsupported mount format {fmt!r}, expected {MOUNT_FORMAT!r}")
    xyz = _numbers(d.get("xyz", [-0.214, -0.044, 0.455]), 3, f"{source}: xyz")
    if "rpy" in d:
        rpy = _numbers(d["rpy"], 3, f"{source}: rpy")
    else:
        rpy = tuple(math.radians(v) for v in _numbers(d.get("rpy_deg", [0.0, 0.0, 0.0]), 3, f"{source}: rpy_deg"))
    cov = d.get("covariance")
    covariance = None if cov is None else _numbers(cov, 36, f"{source}: covariance (36 values, 6x6 row-major)")
    off = _mapping(d.get("encoder_offsets"), f"{source}: encoder_offsets")
    _check_keys(off, {"pan", "tilt"}, f"{source}: encoder_offsets")
    return MountConfig(
        transform=Transform.from_xyz_rpy(*xyz, *rpy),
        parent_frame=_text(d.get("parent_frame", "base_link"), f"{source}: parent_frame"),
        child_frame=_text(d.get("child_frame", "axis_ptz_base"), f"{source}: child_frame"),
        pan_offset=_number(off.get("pan", 0.0), f"{source}: encoder_offsets.pan"),
        tilt_offset=_number(off.get("tilt", 0.0), f"{source}: encoder_offsets.tilt"),
        covariance=covariance,
        comment=str(d.get("comment", "") or ""),
    )


def load_mount(path: str | Path | None = None) -> MountConfig:
    """Load ``config/mount.yaml`` (default) or another mount file."""
    p = Path(path) if path else default_config_path("mount.yaml")
    return mount_from_dict(load_strict(p, ConfigError) or {}, str(p))


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
        default_factory=lambda: SensorPose("panorama_link", Transform.from_xyz_rpy(0.216, -0.044, 0.75, 0, 0, 0))
    )
    laser: SensorPose = field(
        default_factory=lambda: SensorPose("laser_link", Transform.from_xyz_rpy(0.25, 0.0, 0.40, 0, 0, 0))
    )
    ground_z: float = 0.0
    default_range: float = 10.0
    depth_cone_deg: float = 1.0


def _sensor(d: Any, default: SensorPose, where: str) -> SensorPose:
    d = _mapping(d, where)
    if not d:
        return default
    _check_keys(d, {"frame", "xyz", "rpy"}, where)
    xyz = _numbers(d.get("xyz", [0.0, 0.0, 0.0]), 3, f"{where}.xyz")
    rpy = _numbers(d.get("rpy", [0.0, 0.0, 0.0]), 3, f"{where}.rpy")
    return SensorPose(_text(d.get("frame", default.frame), f"{where}.frame"), Transform.from_xyz_rpy(*xyz, *rpy))


_ROBOT_KEYS = {"format", "base_frame", "panorama", "laser", "ground_z", "default_range", "depth_cone_deg"}


def robot_from_dict(d: dict[str, Any], source: str = "<robot>") -> RobotConfig:
    """Parse a ``robot/v1`` mapping; raises :class:`ConfigError` naming the field."""
    d = _mapping(d, source)
    _check_keys(d, _ROBOT_KEYS, source)
    fmt = d.get("format", ROBOT_FORMAT)
    if fmt != ROBOT_FORMAT:
        raise ConfigError(f"{source}: unsupported robot format {fmt!r}, expected {ROBOT_FORMAT!r}")
    base = RobotConfig()
    default_range = _number(d.get("default_range", base.default_range), f"{source}: default_range")
    cone = _number(d.get("depth_cone_deg", base.depth_cone_deg), f"{source}: depth_cone_deg")
    if default_range <= 0:
        raise ConfigError(f"{source}: default_range must be > 0 m, got {default_range}")
    if not 0 < cone < 90:
        raise ConfigError(f"{source}: depth_cone_deg must be in (0, 90) degrees, got {cone}")
    return RobotConfig(
        base_frame=_text(d.get("base_frame", base.base_frame), f"{source}: base_frame"),
        panorama=_sensor(d.get("panorama"), base.panorama, f"{source}: panorama"),
        laser=_sensor(d.get("laser"), base.laser, f"{source}: laser"),
        ground_z=_number(d.get("ground_z", base.ground_z), f"{source}: ground_z"),
        default_range=default_range,
        depth_cone_deg=cone,
    )


def load_robot(path: str | Path | None = None) -> RobotConfig:
    """Load ``config/robot.yaml`` (default) or another robot file."""
    p = Path(path) if path else default_config_path("robot.yaml")
    return robot_from_dict(load_strict(p, ConfigError) or {}, str(p))
