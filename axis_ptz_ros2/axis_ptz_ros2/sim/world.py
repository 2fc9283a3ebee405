"""The simulated robot and its surroundings as configured (``config/sim_world.yaml``), ROS-free.

Frames: everything is expressed in ``base_link`` (REP-103, x forward, y left, z up, metres). :class:`SimWorld`
holds the true poses of the PTZ head, the panorama camera and the laser, the head's kinematics, limits and zoom
model, and the :class:`TargetSpec` s that :mod:`axis_ptz_ros2.sim.scene` turns into textured targets.

:func:`load_world` refuses a malformed file with a :class:`WorldError` (a ``ValueError``) that names the file, the
target and the field: unknown keys, values of the wrong type or length, non-finite numbers, sizes that are not
positive or beyond :data:`MAX_TARGET_SIZE_M`, and for ``image`` targets a missing, unreadable, corrupt or too
large image file (per image at most ``textures.MAX_IMAGE_SIDE`` pixels a side and ``textures.MAX_IMAGE_PIXELS``
pixels; all targets' textures together at most :data:`MAX_TOTAL_TEXELS`). An image ``file`` is a path relative
to the world file's folder, an absolute path, or ``asset:NAME`` for a file shipped in ``sim/assets/``.
"""

from __future__ import annotations

import hashlib
import math
import os
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np

from axis_ptz_ros2.config import default_config_path, load_camera_model
from axis_ptz_ros2.geometry import PtzKinematics
from axis_ptz_ros2.optics import ZoomModel
from axis_ptz_ros2.sim import textures
from axis_ptz_ros2.strict_yaml import load_strict
from axis_ptz_ros2.transforms import FloatArray, Transform

#: Target kinds: the procedural textures of ``sim/textures.py`` and ``image`` (a PNG/JPEG file).
TARGET_KINDS = ("plate", "hazard", "person", "marker", "calib", "checker", "facade", "image")
MAX_TARGET_SIZE_M = 500.0  #: metres: the widest or tallest target
MAX_COORDINATE_M = 10_000.0  #: metres: the farthest a pose or target centre may be from base_link
#: level-0 texels of all targets' textures together (4 bytes each, a third more for mips: at most 1.3 GiB)
MAX_TOTAL_TEXELS = 16 * textures.MAX_IMAGE_PIXELS
MIN_TEXTURE_SIDE = 8  #: texels: a procedural texture narrower than this (an extreme aspect ratio) is refused
ASSET_PREFIX = "asset:"  #: ``file: asset:NAME``: a file shipped in the module's sim/assets/ folder
ASSETS_DIR = Path(__file__).resolve().parent / "assets"


@dataclass(frozen=True, slots=True)
class PtzLimits:
    """``PTZ.Limit.L1`` of the simulated camera (VAPIX degrees and zoom units)."""

    min_pan: float = -170.0
    max_pan: float = 170.0
    min_tilt: float = -30.0
    max_tilt: float = 90.0
    min_zoom: int = 1
    max_zoom: int = 9999


@dataclass(frozen=True, slots=True)
class TargetSpec:
    """Configuration of one planar target (see ``config/sim_world.yaml``)."""

    name: str
    kind: str
    center: tuple[float, float, float]
    size: tuple[float, float]
    text: str = ""
    color: tuple[int, int, int] = (0, 0, 255)  # BGR
    normal: tuple[float, float, float] | None = None  # None: face the PTZ head, upright
    up: tuple[float, float, float] = (0.0, 0.0, 1.0)
    file: str = ""  #: ``image`` targets: the resolved (absolute) path of the picture
    file_sha1: str = ""  #: ``image`` targets: digest of the file's bytes (a changed file is a different world)
    image_size: tuple[int, int] = (0, 0)  #: ``image`` targets: the picture's (width, height) in pixels


class WorldError(ValueError):
    """A world file is malformed; the message names the file, the target and the field, and what is accepted."""


def target_frame(
    center: FloatArray, normal: FloatArray | None, up: FloatArray, facing_point: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(normal, right, up) unit vectors of a target: ``normal`` given, or facing ``facing_point`` (turned about the
    vertical only, unless straight above or below it). Raises ``ValueError`` for a degenerate frame (a zero normal,
    an ``up`` along the normal)."""
    if normal is None:
        to_cam = np.array(facing_point, dtype=np.float64) - center
        if np.linalg.norm(to_cam[:2]) > 1e-6:
            to_cam[2] = 0.0
        n = to_cam
    else:
        n = np.asarray(normal, dtype=np.float64)
    nn = float(np.linalg.norm(n))
    if not math.isfinite(nn) or nn < 1e-9:
        raise ValueError("the normal is zero (or the target's centre is the PTZ head's)")
    n = n / nn
    u = np.asarray(up, dtype=np.float64)
    right = np.cross(u, n)
    nr = float(np.linalg.norm(right))
    if not math.isfinite(nr) or nr < 1e-9 * max(float(np.linalg.norm(u)), 1e-300):
        raise ValueError(f"up {list(map(float, u))} is zero or along the normal {[round(float(v), 6) for v in n]}")
    right = right / nr
    return n, right, np.cross(n, right)


#: the camera-model file whose zoom model a world without ``ptz.zoom_model`` takes (config/, or the installed
#: share/axis_ptz_ros2/config): the simulated camera's default persona, the Axis 214
DEFAULT_CAMERA_MODEL_FILE = "axis214.yaml"


@cache
def default_zoom_model() -> ZoomModel:
    """The zoom model of :data:`DEFAULT_CAMERA_MODEL_FILE`, through the camera-model loader (the camera's facts
    live in its YAML file only); read once. Raises :class:`~axis_ptz_ros2.config.CameraModelError` (a
    ``ValueError``) naming the file when it cannot be read."""
    return load_camera_model(default_config_path(DEFAULT_CAMERA_MODEL_FILE)).zoom


@dataclass(frozen=True)
class SimWorld:
    """Everything the simulator knows about the robot and its surroundings."""

    T_base_ptz: Transform = field(
        default_factory=lambda: Transform.from_xyz_rpy(
            -0.209, -0.047, 0.462, math.radians(0.4), math.radians(-0.3), math.radians(1.1)
        )
    )
    kinematics: PtzKinematics = field(default_factory=lambda: PtzKinematics(0.0687, (0.03, 0.0, 0.0)))
    limits: PtzLimits = field(default_factory=PtzLimits)
    zoom_model: ZoomModel = field(default_factory=default_zoom_model)
    T_base_pano: Transform = field(default_factory=lambda: Transform.from_xyz_rpy(0.216, -0.044, 0.75, 0, 0, 0))
    T_base_laser: Transform = field(default_factory=lambda: Transform.from_xyz_rpy(0.25, 0.0, 0.40, 0, 0, 0))
    targets: tuple[TargetSpec, ...] = ()
    equirect_width: int = 4096

    @property
    def pan_tilt_centre(self) -> FloatArray:
        """The point where the pan and tilt axes meet, in ``base_link``."""
        return self.T_base_ptz.apply(np.array([0.0, 0.0, self.kinematics.h_tilt]))

    def cache_key(self) -> tuple[Any, ...]:
        """A hashable identity of the world (for sharing a built :class:`Scene` between cameras)."""
        return (
            tuple(np.round(self.T_base_ptz.matrix(), 9).ravel()),
            self.kinematics,
            self.targets,
            self.equirect_width,
        )


def _mapping(d: Any, where: str) -> dict[str, Any]:
    if d is None:
        return {}
    if not isinstance(d, dict):
        raise WorldError(f"{where}: expected a mapping, got {d!r}")
    return d


def _check_keys(d: dict[str, Any], allowed: set[str] | tuple[str, ...], where: str) -> None:
    unknown = sorted(str(k) for k in d if k not in allowed)
    if unknown:
        raise WorldError(f"{where}: unknown field(s) {unknown}; allowed: {sorted(allowed)}")


def _number(value: Any, where: str, lo: float = -math.inf, hi: float = math.inf) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise WorldError(f"{where}: expected a number, got {value!r}")
    try:
        result = float(value)
    except OverflowError:
        result = math.inf
    if not math.isfinite(result):
        raise WorldError(f"{where}: expected a finite number, got {value!r}")
    if not lo <= result <= hi:
        raise WorldError(f"{where}: {value!r} is out of range [{lo:g}, {hi:g}]")
    return result


def _integer(value: Any, where: str, lo: int, hi: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise WorldError(f"{where}: expected an integer, got {value!r}")
    if isinstance(value, float) and not (math.isfinite(value) and value.is_integer()):
        raise WorldError(f"{where}: expected an integer, got {value!r}")
    result = int(value)
    if not lo <= result <= hi:
        raise WorldError(f"{where}: {value!r} is out of range [{lo}, {hi}]")
    return result


def _numbers(value: Any, n: int, where: str, lo: float = -math.inf, hi: float = math.inf) -> tuple[float, ...]:
    if not isinstance(value, list | tuple) or len(value) != n:
        raise WorldError(f"{where}: expected a list of {n} numbers, got {value!r}")
    return tuple(_number(v, f"{where}[{i}]", lo, hi) for i, v in enumerate(value))


def _pose(d: dict[str, Any], xyz_key: str, rpy_key: str, xyz_default: list[float], where: str) -> Transform:
    xyz = _numbers(d.get(xyz_key, xyz_default), 3, f"{where}.{xyz_key}", -MAX_COORDINATE_M, MAX_COORDINATE_M)
    rpy = _numbers(d.get(rpy_key, [0.0, 0.0, 0.0]), 3, f"{where}.{rpy_key} (degrees)", -360.0, 360.0)
    return Transform.from_xyz_rpy(*xyz, *(math.radians(v) for v in rpy))


def _zoom_model(d: Any, where: str) -> ZoomModel:
    d = _mapping(d, where)
    _check_keys(d, set(ZoomModel.__dataclass_fields__), where)
    kw: dict[str, Any] = {}
    for k, v in d.items():
        if k == "curve":
            if not isinstance(v, str):
                raise WorldError(f"{where}.curve: expected a string, got {v!r}")
            kw[k] = v
        elif k == "table":
            if not isinstance(v, list) or not all(isinstance(p, list | tuple) and len(p) == 2 for p in v):
                raise WorldError(f"{where}.table: expected a list of [zoom, magnification] pairs, got {v!r}")
            kw[k] = [list(_numbers(p, 2, f"{where}.table[{i}]", 0.0, 1e6)) for i, p in enumerate(v)]
        elif k == "square_pixels":
            if not isinstance(v, bool):
                raise WorldError(f"{where}.square_pixels: expected true or false, got {v!r}")
            kw[k] = v
        elif k in ("min_zoom", "max_zoom", "optical_max_zoom"):
            kw[k] = _integer(v, f"{where}.{k}", 0, 1_000_000)
        else:
            kw[k] = _number(v, f"{where}.{k}", 0.0, 1e6)
    try:
        return ZoomModel.from_dict(kw)
    except (TypeError, ValueError) as err:
        raise WorldError(f"{where}: {err}") from err


def _resolve_image(value: Any, where: str, base_dir: Path | None) -> Path:
    if not isinstance(value, str) or not value.strip():
        raise WorldError(f"{where}: expected a path to a PNG or JPEG file, got {value!r}")
    if "\x00" in value:
        raise WorldError(f"{where}: a path with a NUL character: {value!r}")
    if value.startswith(ASSET_PREFIX):
        name = value[len(ASSET_PREFIX) :]
        if not name or Path(name).is_absolute() or ".." in Path(name).parts:
            raise WorldError(f"{where}: {value!r}: an asset is a file name in {ASSETS_DIR}")
        return ASSETS_DIR / name
    p = Path(os.path.expanduser(value))
    if not p.is_absolute():
        p = (base_dir if base_dir is not None else Path.cwd()) / p
    return p


_IMAGE_CHECKS: dict[tuple[str, int, int], tuple[str, tuple[int, int]]] = {}


def _check_image(path: Path, where: str) -> tuple[str, tuple[int, int]]:
    """(sha1 of the bytes, (width, height)) of a usable image file, else a :class:`WorldError` saying why."""
    try:
        st = path.stat()
    except OSError as err:
        raise WorldError(f"{where}: {path}: no such image file ({err.strerror or err})") from err
    if not path.is_file():
        raise WorldError(f"{where}: {path}: not a file")
    key = (str(path), st.st_mtime_ns, st.st_size)
    known = _IMAGE_CHECKS.get(key)
    if known is not None:
        return known
    if st.st_size > textures.MAX_IMAGE_FILE_BYTES:
        raise WorldError(
            f"{where}: {path}: file of {st.st_size} bytes; at most {textures.MAX_IMAGE_FILE_BYTES} bytes allowed"
        )
    try:
        data = path.read_bytes()
    except OSError as err:
        raise WorldError(f"{where}: {path}: cannot read: {err.strerror or err}") from err
    try:
        img = textures.decode_image(data)
    except textures.ImageError as err:
        raise WorldError(f"{where}: {path}: {err}") from err
    result = (hashlib.sha1(data).hexdigest(), (int(img.shape[1]), int(img.shape[0])))
    if len(_IMAGE_CHECKS) > 64:
        _IMAGE_CHECKS.clear()
    _IMAGE_CHECKS[key] = result
    return result


_COMMON_TARGET_KEYS = ("name", "kind", "center", "size", "facing", "normal", "up")
_KIND_KEYS: dict[str, tuple[str, ...]] = {
    "plate": ("text",),
    "hazard": ("text",),
    "facade": ("text",),
    "marker": ("color",),
    "image": ("file",),
}


def _target(t: Any, i: int, source: str, base_dir: Path | None, facing_point: FloatArray) -> TargetSpec:
    where = f"{source}: targets[{i}]"
    if not isinstance(t, dict):
        raise WorldError(f"{where}: expected a mapping {{name, kind, center, size, ...}}, got {t!r}")
    name = t.get("name")
    if not isinstance(name, str) or not name.strip():
        raise WorldError(f"{where}.name: expected a non-empty string, got {name!r}")
    where = f"{source}: target {name!r}"
    kind = t.get("kind")
    if kind not in TARGET_KINDS:
        raise WorldError(f"{where}.kind: {kind!r} is not one of {list(TARGET_KINDS)}")
    _check_keys(t, set(_COMMON_TARGET_KEYS) | set(_KIND_KEYS.get(kind, ())), f"{where} (kind {kind})")
    for key in ("center", "size"):
        if key not in t:
            raise WorldError(f"{where}: missing {key}")
    center = _numbers(t["center"], 3, f"{where}.center", -MAX_COORDINATE_M, MAX_COORDINATE_M)
    size = _numbers(t["size"], 2, f"{where}.size (metres)", -math.inf, math.inf)
    if not all(0.0 < v <= MAX_TARGET_SIZE_M for v in size):
        raise WorldError(f"{where}.size: {list(size)} m; each side must be > 0 and <= {MAX_TARGET_SIZE_M:g} m")
    facing = t.get("facing", "ptz" if "normal" not in t else "normal")
    if facing not in ("ptz", "normal"):
        raise WorldError(f"{where}.facing: {facing!r}; expected 'ptz' (turned towards the PTZ head) or 'normal'")
    if facing == "ptz" and "normal" in t:
        raise WorldError(f"{where}: facing 'ptz' and a normal: give one of them")
    if facing == "normal" and "normal" not in t:
        raise WorldError(f"{where}: facing 'normal' needs a normal: [x, y, z]")
    normal = _numbers(t["normal"], 3, f"{where}.normal", -1e6, 1e6) if "normal" in t else None
    up = _numbers(t.get("up", [0.0, 0.0, 1.0]), 3, f"{where}.up", -1e6, 1e6)
    try:
        target_frame(np.asarray(center), None if normal is None else np.asarray(normal), np.asarray(up), facing_point)
    except ValueError as err:
        raise WorldError(f"{where}: {err}") from err
    text = t.get("text", "")
    if isinstance(text, int) and not isinstance(text, bool):
        text = str(text)
    if not isinstance(text, str) or len(text) > 64:
        raise WorldError(f"{where}.text: expected a string of at most 64 characters, got {text!r}")
    color = (0, 0, 255)
    if "color" in t:
        c = t["color"]
        if not isinstance(c, list | tuple) or len(c) != 3:
            raise WorldError(f"{where}.color: expected [b, g, r] (0-255 each), got {c!r}")
        color = tuple(_integer(v, f"{where}.color[{k}]", 0, 255) for k, v in enumerate(c))  # type: ignore[assignment]
    file, digest, image_size = "", "", (0, 0)
    if kind == "image":
        if "file" not in t:
            raise WorldError(f"{where}: an image target needs file: PATH (PNG or JPEG)")
        path = _resolve_image(t["file"], f"{where}.file", base_dir)
        digest, image_size = _check_image(path, f"{where}.file")
        file = str(path)
    else:
        cols, rows = textures.texture_shape(kind, size[0], size[1])
        if min(cols, rows) < MIN_TEXTURE_SIDE or cols * rows > textures.MAX_IMAGE_PIXELS:
            raise WorldError(
                f"{where}.size: {list(size)} m makes a {cols}x{rows} texture for kind {kind}; each side must be "
                f">= {MIN_TEXTURE_SIDE} and at most {textures.MAX_IMAGE_PIXELS} texels in all (aspect ratio too "
                "extreme or target too large)"
            )
    return TargetSpec(
        name=name,
        kind=kind,
        center=(center[0], center[1], center[2]),
        size=(size[0], size[1]),
        text=text,
        color=color,
        normal=None if normal is None else (normal[0], normal[1], normal[2]),
        up=(up[0], up[1], up[2]),
        file=file,
        file_sha1=digest,
        image_size=image_size,
    )


def _texels(spec: TargetSpec) -> int:
    if spec.kind == "image":
        return spec.image_size[0] * spec.image_size[1]
    cols, rows = textures.texture_shape(spec.kind, *spec.size)
    return cols * rows


_TOP_KEYS = {"ptz", "panorama", "laser", "background", "targets"}
_PTZ_KEYS = {"mount_xyz", "mount_rpy_deg", "h_tilt", "d_opt", "limits", "zoom_model"}


def world_from_dict(cfg: dict[str, Any], source: str = "<world>", base_dir: Path | None = None) -> SimWorld:
    """Build a :class:`SimWorld` from a parsed ``sim_world.yaml`` mapping (missing keys take defaults).

    Raises :class:`WorldError` naming the field (and the target) for anything else than the documented shape;
    ``image`` targets' files are resolved against ``base_dir`` (the world file's folder), read and checked."""
    cfg = _mapping(cfg, source)
    _check_keys(cfg, _TOP_KEYS, source)
    default = SimWorld()
    ptz = _mapping(cfg.get("ptz"), f"{source}: ptz")
    _check_keys(ptz, _PTZ_KEYS, f"{source}: ptz")
    lim = _mapping(ptz.get("limits"), f"{source}: ptz.limits")
    _check_keys(lim, set(PtzLimits.__dataclass_fields__), f"{source}: ptz.limits")
    w = f"{source}: ptz.limits"
    limits = PtzLimits(
        _number(lim.get("min_pan", -170.0), f"{w}.min_pan", -360.0, 360.0),
        _number(lim.get("max_pan", 170.0), f"{w}.max_pan", -360.0, 360.0),
        _number(lim.get("min_tilt", -30.0), f"{w}.min_tilt", -180.0, 180.0),
        _number(lim.get("max_tilt", 90.0), f"{w}.max_tilt", -180.0, 180.0),
        _integer(lim.get("min_zoom", 1), f"{w}.min_zoom", 0, 1_000_000),
        _integer(lim.get("max_zoom", 9999), f"{w}.max_zoom", 0, 1_000_000),
    )
    if limits.min_pan > limits.max_pan or limits.min_tilt > limits.max_tilt or limits.min_zoom >= limits.max_zoom:
        raise WorldError(f"{w}: each minimum must be below its maximum, got {limits}")
    zm = _zoom_model(ptz["zoom_model"], f"{source}: ptz.zoom_model") if "zoom_model" in ptz else default.zoom_model
    d_opt = _numbers(ptz.get("d_opt", [0.03, 0.0, 0.0]), 3, f"{source}: ptz.d_opt", -10.0, 10.0)
    kinematics = PtzKinematics(
        _number(ptz.get("h_tilt", 0.0687), f"{source}: ptz.h_tilt", -10.0, 10.0), (d_opt[0], d_opt[1], d_opt[2])
    )
    has_mount = "mount_xyz" in ptz or "mount_rpy_deg" in ptz
    T_base_ptz = (
        _pose(ptz, "mount_xyz", "mount_rpy_deg", [-0.209, -0.047, 0.462], f"{source}: ptz")
        if has_mount
        else default.T_base_ptz
    )
    poses = {}
    for key, xyz_default, fallback in (
        ("panorama", [0.216, -0.044, 0.75], default.T_base_pano),
        ("laser", [0.25, 0.0, 0.40], default.T_base_laser),
    ):
        sub = _mapping(cfg.get(key), f"{source}: {key}")
        _check_keys(sub, {"xyz", "rpy_deg"}, f"{source}: {key}")
        poses[key] = _pose(sub, "xyz", "rpy_deg", xyz_default, f"{source}: {key}") if sub else fallback
    bg = _mapping(cfg.get("background"), f"{source}: background")
    _check_keys(bg, {"equirect_width"}, f"{source}: background")
    eq_w = _integer(bg.get("equirect_width", 4096), f"{source}: background.equirect_width", 256, 16384)
    if eq_w % 2:
        raise WorldError(f"{source}: background.equirect_width: {eq_w} must be even (height = width / 2)")
    raw_targets = cfg.get("targets", [])
    if raw_targets is None:
        raw_targets = []
    if not isinstance(raw_targets, list):
        raise WorldError(f"{source}: targets: expected a list, got {raw_targets!r}")
    facing_point = T_base_ptz.apply(np.array([0.0, 0.0, kinematics.h_tilt]))
    targets = [_target(t, i, source, base_dir, facing_point) for i, t in enumerate(raw_targets)]
    names = [t.name for t in targets]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise WorldError(f"{source}: targets: the names {dup} are used more than once (a name is unique)")
    total = sum(_texels(t) for t in targets)
    if total > MAX_TOTAL_TEXELS:
        raise WorldError(
            f"{source}: targets: their textures hold {total} texels together; at most {MAX_TOTAL_TEXELS} "
            f"({MAX_TOTAL_TEXELS // textures.MAX_IMAGE_PIXELS} images of "
            f"{textures.MAX_IMAGE_SIDE}x{textures.MAX_IMAGE_SIDE}) allowed"
        )
    return SimWorld(
        T_base_ptz=T_base_ptz,
        kinematics=kinematics,
        limits=limits,
        zoom_model=zm,
        T_base_pano=poses["panorama"],
        T_base_laser=poses["laser"],
        targets=tuple(targets),
        equirect_width=eq_w,
    )


def load_world(path: str | Path | None = None) -> SimWorld:
    """Load the world from a YAML file (default: the repository's ``config/sim_world.yaml``).

    Raises :class:`WorldError` (a ``ValueError``) for an unreadable file, broken YAML, duplicate keys and every
    malformed field, naming the file (and the target)."""
    # default: the repository's file, or the installed share/axis_ptz_ros2/config copy (colcon)
    p = Path(path) if path is not None else default_config_path("sim_world.yaml")
    return world_from_dict(load_strict(p, WorldError) or {}, str(p), p.resolve().parent)
