"""Where a camera's calibration lives, as ROS' ``camera_info_manager`` does it (ROS-free).

``camera_info_url`` names the calibration file:

* ``file:///abs/path/${NAME}.yaml`` — a file; ``${NAME}`` is the camera name, ``${ROS_HOME}`` the ROS home
  directory (``$ROS_HOME``, else ``~/.ros``);
* ``package://pkg/rel/path.yaml`` — a file under the package's share directory (found with ament_index);
* ``""`` — the default location ``${ROS_HOME}/camera_info/${NAME}.yaml``.

Any other scheme, and a name with other than letters, digits and ``_``, is refused with the reason. The file is
the standard calibration YAML (:mod:`axis_ptz_ros2.camera_info`) that ``camera_calibration`` and
``camera_info_manager`` write. A stored calibration also records, in a comment line the standard parsers skip,
the zoom (VAPIX units) it was taken at, so the zoom-aware camera_info
(:meth:`axis_ptz_ros2.config.CameraModel.camera_info_at`) scales K from there: ``model.with_camera_info(
store.calibration, store.zoom)``.

:meth:`CameraInfoStore.store` is the ``set_camera_info`` service's body: it refuses wrong matrix sizes, a size
that differs from the stream and anything :class:`~axis_ptz_ros2.camera_info.CameraInfoData` refuses, writes
to a temporary file in the target directory and renames it over the old file (a failed write leaves the old
file whole), and only then makes the new calibration current. A refusal keeps the previous calibration.
"""

from __future__ import annotations

import contextlib
import os
import re
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from axis_ptz_ros2.camera_info import (
    CameraInfoData,
    CameraInfoError,
    camera_info_from_dict,
    dump_camera_info,
)
from axis_ptz_ros2.strict_yaml import YamlError, loads_strict

#: The comment line that records the zoom a stored calibration was taken at (the YAML parsers skip it).
ZOOM_COMMENT = "# axis_ptz_ros2 camera_info_zoom:"
_NAME_RE = re.compile(r"^[A-Za-z0-9_]+$")
_ZOOM_RE = re.compile(r"^# axis_ptz_ros2 camera_info_zoom:\s*(\S+)\s*$", re.MULTILINE)


class CameraInfoUrlError(ValueError):
    """A ``camera_info_url`` (or camera name) that cannot be resolved; the message says why."""


def ros_home(env: dict[str, str] | None = None) -> Path:
    """``$ROS_HOME``, else ``~/.ros`` (as rcutils / camera_info_manager)."""
    e = os.environ if env is None else env
    return Path(e["ROS_HOME"]) if e.get("ROS_HOME") else Path(e.get("HOME", str(Path.home()))) / ".ros"


def package_share(package: str) -> Path:
    """The share directory of an installed ROS package (ament_index); raises :class:`CameraInfoUrlError`."""
    try:
        from ament_index_python.packages import (  # noqa: PLC0415  # optional: a plain install has no ament_index
            PackageNotFoundError,
            get_package_share_directory,
        )
    except ImportError as err:
        raise CameraInfoUrlError(f"package://{package}/...: ament_index_python is not installed") from err
    try:
        return Path(get_package_share_directory(package))
    except (PackageNotFoundError, ValueError) as err:
        raise CameraInfoUrlError(f"package://{package}/...: package {package!r} not found ({err})") from err


def validate_camera_name(name: str) -> None:
    """Letters, digits and ``_`` only (camera_info_manager's rule: the name becomes part of a file name)."""
    if not _NAME_RE.match(name):
        raise CameraInfoUrlError(
            f"camera name {name!r}: only letters, digits and '_' are allowed (it becomes part of a file name)"
        )


def resolve_url(
    url: str,
    camera_name: str,
    *,
    env: dict[str, str] | None = None,
    find_share: Callable[[str], Path] = package_share,
) -> Path:
    """The file ``url`` names for ``camera_name`` (see the module docstring); raises :class:`CameraInfoUrlError`
    with the reason for an unknown scheme, a relative or empty path, or a package that is not installed."""
    validate_camera_name(camera_name)
    url = url.strip()
    if not url:
        url = "file://${ROS_HOME}/camera_info/${NAME}.yaml"
    url = url.replace("${NAME}", camera_name).replace("${ROS_HOME}", str(ros_home(env)))
    if "${" in url:
        raise CameraInfoUrlError(f"camera_info_url {url!r}: unknown variable (only ${{NAME}} and ${{ROS_HOME}})")
    scheme, sep, rest = url.partition("://")
    if not sep:
        raise CameraInfoUrlError(f"camera_info_url {url!r}: no scheme; use file:///path or package://pkg/path")
    scheme = scheme.lower()
    if scheme == "file":
        if not rest.startswith("/"):
            raise CameraInfoUrlError(f"camera_info_url {url!r}: file:// needs an absolute path (file:///...)")
        if rest.endswith("/"):
            raise CameraInfoUrlError(f"camera_info_url {url!r}: names a directory, not a file")
        return Path(rest)
    if scheme == "package":
        pkg, _, rel = rest.partition("/")
        if not pkg or not rel or rel.endswith("/"):
            raise CameraInfoUrlError(f"camera_info_url {url!r}: package:// needs package://<package>/<file>")
        if ".." in Path(rel).parts:
            raise CameraInfoUrlError(f"camera_info_url {url!r}: '..' may not leave the package's share directory")
        return find_share(pkg) / rel
    raise CameraInfoUrlError(
        f"camera_info_url {url!r}: unsupported scheme {scheme + '://'!r}; use file:// or package:// (or '' for "
        f"{ros_home(env)}/camera_info/{camera_name}.yaml)"
    )


def parse_calibration(text: str, source: str) -> tuple[CameraInfoData, float | None]:
    """The calibration in ``text`` (standard YAML) and the zoom recorded with it (``None`` if not recorded);
    raises :class:`CameraInfoError` naming the problem."""
    try:
        doc = loads_strict(text, source)
    except YamlError as err:
        raise CameraInfoError(str(err)) from err
    ci = camera_info_from_dict(doc, source)
    zoom: float | None = None
    m = _ZOOM_RE.search(text)
    if m:
        try:
            zoom = float(m.group(1))
        except ValueError as err:
            raise CameraInfoError(f"{source}: {ZOOM_COMMENT} {m.group(1)!r} is not a number") from err
    return ci, zoom


def format_calibration(ci: CameraInfoData, zoom: float | None) -> str:
    """The standard YAML text, preceded by the zoom comment when ``zoom`` is known."""
    head = f"{ZOOM_COMMENT} {float(zoom)!r}\n" if zoom is not None else ""
    return head + dump_camera_info(ci)


def write_atomically(path: Path, text: str) -> None:
    """Write ``text`` to a temporary file beside ``path``, fsync it and rename it over ``path`` (creating the
    directory as camera_info_manager does). Raises :class:`OSError`; ``path`` is then untouched."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def calibration_from_fields(
    width: int,
    height: int,
    distortion_model: str,
    d: Sequence[float],
    k: Sequence[float],
    r: Sequence[float],
    p: Sequence[float],
    camera_name: str = "",
    source: str = "set_camera_info",
) -> CameraInfoData:
    """A calibration from the fields of a ``sensor_msgs/CameraInfo`` (raises :class:`CameraInfoError` for
    wrong matrix sizes or values :class:`CameraInfoData` refuses)."""
    for name, vals, n in (("k", k, 9), ("r", r, 9), ("p", p, 12)):
        if len(vals) != n:
            raise CameraInfoError(f"{source}: {name} needs {n} values, got {len(vals)}")
    try:
        return CameraInfoData(
            width=int(width),
            height=int(height),
            K=tuple(float(v) for v in k),
            distortion_model=str(distortion_model),
            D=tuple(float(v) for v in d),
            R=tuple(float(v) for v in r),
            P=tuple(float(v) for v in p),
            camera_name=camera_name,
            source=source,
        )
    except CameraInfoError:
        raise
    except (TypeError, ValueError) as err:  # a value that is not a number
        raise CameraInfoError(f"{source}: {err}") from err


def calibration_from_msg(msg: Any, camera_name: str = "", source: str = "set_camera_info") -> CameraInfoData:
    """:func:`calibration_from_fields` of a ``sensor_msgs/CameraInfo``-like object (duck-typed, no ROS import)."""
    return calibration_from_fields(
        msg.width, msg.height, msg.distortion_model, list(msg.d), list(msg.k), list(msg.r), list(msg.p),
        camera_name, source,
    )  # fmt: skip


@dataclass(frozen=True, slots=True)
class StoreResult:
    """What ``set_camera_info`` answers: ``success`` and ``status_message`` (the reason when refused)."""

    success: bool
    status_message: str


class CameraInfoStore:
    """The calibration of one camera at its ``camera_info_url`` (see the module docstring).

    Not thread-safe: the node calls it from one callback group. ``calibration`` / ``zoom`` are the current
    calibration (``None`` = none stored) and the zoom it was taken at."""

    def __init__(
        self,
        url: str,
        camera_name: str,
        *,
        env: dict[str, str] | None = None,
        find_share: Callable[[str], Path] = package_share,
    ) -> None:
        """Resolve ``url`` now (raises :class:`CameraInfoUrlError` with the reason); nothing is read yet."""
        self.url = url
        self.camera_name = camera_name
        self.path = resolve_url(url, camera_name, env=env, find_share=find_share)
        self.calibration: CameraInfoData | None = None
        self.zoom: float | None = None

    def load(self) -> bool:
        """Read the file: True if a calibration was loaded, False if there is none yet (no file). A malformed
        file raises :class:`CameraInfoError` (the current calibration is kept)."""
        try:
            text = self.path.read_text(encoding="utf-8")
        except FileNotFoundError:
            return False
        except OSError as err:
            raise CameraInfoError(f"{self.path}: cannot read ({err.strerror or err})") from err
        self.calibration, self.zoom = parse_calibration(text, str(self.path))
        return True

    def store(self, ci: CameraInfoData, stream_size: tuple[int, int], zoom: float | None) -> StoreResult:
        """Store ``ci`` (taken at ``zoom`` on a ``stream_size`` stream) and make it current; refused with the
        reason, the previous calibration kept, if its size differs from the stream's or the file cannot be
        written."""
        w, h = stream_size
        if (ci.width, ci.height) != (w, h):
            return StoreResult(
                False, f"refused: calibration is {ci.width}x{ci.height} but the stream is {w}x{h}; kept the previous"
            )
        named = CameraInfoData(
            ci.width, ci.height, ci.K, ci.distortion_model, ci.D, ci.R, ci.P, self.camera_name, str(self.path)
        )
        try:
            write_atomically(self.path, format_calibration(named, zoom))
        except OSError as err:
            return StoreResult(
                False, f"refused: cannot write {self.path} ({err.strerror or err}); kept the previous calibration"
            )
        self.calibration, self.zoom = named, zoom
        return StoreResult(True, f"stored {w}x{h} calibration in {self.path}")

    def store_msg(self, msg: Any, stream_size: tuple[int, int], zoom: float | None) -> StoreResult:
        """:meth:`store` for a ``sensor_msgs/CameraInfo``-like ``msg``; malformed → refused with the reason."""
        try:
            ci = calibration_from_msg(msg, self.camera_name)
        except CameraInfoError as err:
            return StoreResult(False, f"refused: {err}; kept the previous calibration")
        return self.store(ci, stream_size, zoom)
