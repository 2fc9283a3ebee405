"""Measured camera intrinsics: the ROS camera calibration YAML, distortion and undistortion (ROS-free).

The file is the one ROS' ``camera_calibration`` tool writes (``camera_calibration_parsers`` YAML)::

    image_width: 704
    image_height: 576
    camera_name: axis_ptz
    camera_matrix: {rows: 3, cols: 3, data: [fx, 0, cx, 0, fy, cy, 0, 0, 1]}
    distortion_model: plumb_bob            # plumb_bob | rational_polynomial | equidistant
    distortion_coefficients: {rows: 1, cols: 5, data: [k1, k2, p1, p2, k3]}
    rectification_matrix: {rows: 3, cols: 3, data: [1, 0, 0, 0, 1, 0, 0, 0, 1]}
    projection_matrix: {rows: 3, cols: 4, data: [fx', 0, cx', 0, 0, fy', cy', 0, 0, 0, 1, 0]}

Pixel convention (as ROS and OpenCV): ``u`` right, ``v`` down, origin at the centre of the top-left pixel.

Distortion models (normalised coordinates ``x = X/Z``, ``y = Y/Z``, ``r² = x² + y²``):

* ``plumb_bob`` (k1, k2, p1, p2, k3): Brown–Conrady, OpenCV's ``projectPoints``.
* ``rational_polynomial`` (k1, k2, p1, p2, k3, k4, k5, k6): radial ``(1+k1r²+k2r⁴+k3r⁶)/(1+k4r²+k5r⁴+k6r⁶)``.
  OpenCV's thin-prism/tilt terms (coefficients 9–14) are not supported and must be zero.
* ``equidistant`` (k1, k2, k3, k4): OpenCV's ``fisheye`` model, ``θd = θ(1+k1θ²+k2θ⁴+k3θ⁶+k4θ⁸)``.

A zoom lens changes focal length with zoom; :meth:`CameraInfoData.adapted` scales a calibration made at one
zoom and resolution to another (focal length × magnification, principal point and distortion kept). That is
an approximation for a real zoom lens (its principal point and distortion also drift with zoom); it is exact
for a resolution change of the same sensor area.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from axis_ptz_ros2.optics import Intrinsics
from axis_ptz_ros2.strict_yaml import load_strict
from axis_ptz_ros2.vapix.models import MAX_IMAGE_SIDE

FloatArray = npt.NDArray[np.float64]

#: Number of coefficients each supported model uses (extra trailing coefficients must be zero).
DISTORTION_MODELS: dict[str, int] = {"plumb_bob": 5, "rational_polynomial": 8, "equidistant": 4}

_KEYS = {
    "image_width",
    "image_height",
    "camera_name",
    "camera_matrix",
    "distortion_model",
    "distortion_coefficients",
    "rectification_matrix",
    "projection_matrix",
}
_IDENTITY3 = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)


class CameraInfoError(ValueError):
    """A camera calibration file or mapping is malformed; the message names the source and the field."""


@dataclass(frozen=True, slots=True)
class CameraInfoData:
    """One camera calibration: image size, K (row-major 3×3), distortion, R (3×3) and P (3×4)."""

    width: int
    height: int
    K: tuple[float, ...]
    distortion_model: str = "plumb_bob"
    D: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0)
    R: tuple[float, ...] = _IDENTITY3
    P: tuple[float, ...] = ()
    camera_name: str = ""
    source: str = ""

    def __post_init__(self) -> None:
        """Validate (raises :class:`CameraInfoError`)."""
        problem = _problem(self)
        if problem is not None:
            raise CameraInfoError(f"{self.source or 'camera_info'}: {problem}")
        if not self.P:
            fx, fy, cx, cy = self.K[0], self.K[4], self.K[2], self.K[5]
            object.__setattr__(self, "P", (fx, 0.0, cx, 0.0, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0))

    # -- accessors -------------------------------------------------------------------------------------
    @property
    def fx(self) -> float:
        """Focal length in x (px)."""
        return self.K[0]

    @property
    def fy(self) -> float:
        """Focal length in y (px)."""
        return self.K[4]

    @property
    def cx(self) -> float:
        """Principal point x (px)."""
        return self.K[2]

    @property
    def cy(self) -> float:
        """Principal point y (px)."""
        return self.K[5]

    @property
    def coefficients(self) -> FloatArray:
        """The distortion coefficients the model uses (length per :data:`DISTORTION_MODELS`, zero-padded)."""
        n = DISTORTION_MODELS[self.distortion_model]
        d = np.zeros(n)
        m = min(n, len(self.D))
        d[:m] = self.D[:m]
        return d

    @property
    def has_distortion(self) -> bool:
        """True if any distortion coefficient is non-zero."""
        return any(abs(v) > 0.0 for v in self.D)

    def intrinsics(self) -> Intrinsics:
        """The pinhole part (K) as :class:`~axis_ptz_ros2.optics.Intrinsics` (distortion not included)."""
        return Intrinsics(self.width, self.height, self.fx, self.fy, self.cx, self.cy)

    # -- adaptation to another stream ------------------------------------------------------------------
    def adapted(self, width: int, height: int, magnification: float = 1.0) -> CameraInfoData:
        """The calibration for a ``width``×``height`` stream of the same sensor area at ``magnification``
        times the calibrated focal length: K and P focal lengths × magnification × size ratio, principal
        point scaled with the size (pixel-centre convention), distortion and R kept."""
        if width == self.width and height == self.height and magnification == 1.0:
            return self
        sx, sy = width / self.width, height / self.height

        def cu(c: float) -> float:
            return (c + 0.5) * sx - 0.5

        def cv(c: float) -> float:
            return (c + 0.5) * sy - 0.5

        k, p = self.K, self.P
        K = (k[0] * magnification * sx, k[1] * magnification * sx, cu(k[2]), 0.0, k[4] * magnification * sy, cv(k[5]))
        P = (
            p[0] * magnification * sx,
            p[1] * magnification * sx,
            cu(p[2]),
            p[3] * magnification * sx,
            0.0,
            p[5] * magnification * sy,
            cv(p[6]),
            p[7] * magnification * sy,
            *p[8:12],
        )
        return CameraInfoData(
            width, height, (*K, 0.0, 0.0, 1.0), self.distortion_model, self.D, self.R, P, self.camera_name, self.source
        )

    def to_dict(self) -> dict[str, Any]:
        """The ROS camera calibration YAML mapping."""
        return {
            "image_width": int(self.width),
            "image_height": int(self.height),
            "camera_name": self.camera_name or "camera",
            "camera_matrix": {"rows": 3, "cols": 3, "data": [float(v) for v in self.K]},
            "distortion_model": self.distortion_model,
            "distortion_coefficients": {"rows": 1, "cols": len(self.D), "data": [float(v) for v in self.D]},
            "rectification_matrix": {"rows": 3, "cols": 3, "data": [float(v) for v in self.R]},
            "projection_matrix": {"rows": 3, "cols": 4, "data": [float(v) for v in self.P]},
        }


def nominal_camera_info(intr: Intrinsics) -> CameraInfoData:
    """A distortion-free calibration from pinhole intrinsics (what a camera model without measurements gives)."""
    return CameraInfoData(intr.width, intr.height, tuple(float(v) for v in intr.K.reshape(-1)))


def _problem(ci: CameraInfoData) -> str | None:
    for name, side in (("image_width", ci.width), ("image_height", ci.height)):
        if isinstance(side, bool) or not isinstance(side, int) or not 1 <= side <= MAX_IMAGE_SIDE:
            return f"{name} must be an integer in 1..{MAX_IMAGE_SIDE}, got {side!r}"
    for name, vals, n in (("camera_matrix", ci.K, 9), ("rectification_matrix", ci.R, 9)):
        if len(vals) != n or not all(math.isfinite(v) for v in vals):
            return f"{name} needs {n} finite numbers, got {list(vals)}"
    if ci.P and (len(ci.P) != 12 or not all(math.isfinite(v) for v in ci.P)):
        return f"projection_matrix needs 12 finite numbers, got {list(ci.P)}"
    k = ci.K
    if not (k[0] > 0 and k[4] > 0):
        return f"camera_matrix: fx and fy must be positive, got fx {k[0]}, fy {k[4]}"
    if abs(k[1]) > 1e-6 * k[0]:
        return f"camera_matrix: skew {k[1]} is not supported (the ROS camera_calibration tool writes 0)"
    if k[3] != 0.0 or k[6] != 0.0 or k[7] != 0.0 or k[8] != 1.0:
        return f"camera_matrix: the last row must be [0, 0, 1] and K[1][0] 0, got {list(k)}"
    if not (-0.5 <= k[2] <= ci.width - 0.5 and -0.5 <= k[5] <= ci.height - 0.5):
        return f"camera_matrix: principal point ({k[2]}, {k[5]}) is outside the {ci.width}x{ci.height} image"
    if ci.distortion_model not in DISTORTION_MODELS:
        return f"distortion_model {ci.distortion_model!r} is not supported; use one of {sorted(DISTORTION_MODELS)}"
    if not all(math.isfinite(v) for v in ci.D):
        return f"distortion_coefficients must be finite, got {list(ci.D)}"
    n = DISTORTION_MODELS[ci.distortion_model]
    if len(ci.D) < n and any(ci.D):
        return f"{ci.distortion_model} needs {n} distortion coefficients, got {len(ci.D)}"
    if any(v != 0.0 for v in ci.D[n:]):
        return (
            f"{ci.distortion_model}: only the first {n} distortion coefficients are supported; coefficients "
            f"{list(ci.D[n:])} beyond them must be 0"
        )
    return None


# --------------------------------------------------------------------------------------------------------
# Reading and writing
# --------------------------------------------------------------------------------------------------------
def _matrix(d: dict[str, Any], key: str, rows: int | None, cols: int | None, source: str) -> tuple[float, ...]:
    m = d[key]
    if isinstance(m, list):  # tolerate a bare list of numbers
        data = m
    elif isinstance(m, dict):
        unknown = sorted(str(k) for k in m if k not in {"rows", "cols", "data"})
        if unknown:
            raise CameraInfoError(f"{source}: {key}: unknown field(s) {unknown}; allowed: rows, cols, data")
        if "data" not in m:
            raise CameraInfoError(f"{source}: {key}: missing 'data'")
        data = m["data"]
        r, c = m.get("rows"), m.get("cols")
        if not isinstance(data, list):
            raise CameraInfoError(f"{source}: {key}.data: expected a list of numbers, got {data!r}")
        if r is not None and c is not None:
            if not isinstance(r, int) or not isinstance(c, int) or r * c != len(data):
                raise CameraInfoError(f"{source}: {key}: rows {r!r} x cols {c!r} does not match {len(data)} values")
            if rows is not None and cols is not None and (r, c) != (rows, cols):
                raise CameraInfoError(f"{source}: {key}: expected {rows}x{cols}, got {r}x{c}")
    else:
        raise CameraInfoError(f"{source}: {key}: expected a mapping with rows, cols and data, got {m!r}")
    out = []
    for i, x in enumerate(data):
        try:
            finite = not isinstance(x, bool) and isinstance(x, int | float) and math.isfinite(float(x))
        except OverflowError:  # an integer beyond a double (found by the fuzz tier)
            finite = False
        if not finite:
            raise CameraInfoError(f"{source}: {key}.data[{i}]: expected a finite number, got {x!r}")
        out.append(float(x))
    return tuple(out)


def camera_info_from_dict(d: Any, source: str = "<camera_info>") -> CameraInfoData:
    """Parse a ROS camera calibration mapping (raises :class:`CameraInfoError` naming the field)."""
    if not isinstance(d, dict):
        raise CameraInfoError(f"{source}: expected a camera calibration mapping, got {type(d).__name__}")
    unknown = sorted(str(k) for k in d if k not in _KEYS)
    if unknown:
        raise CameraInfoError(f"{source}: unknown field(s) {unknown}; allowed: {sorted(_KEYS)}")
    for key in ("image_width", "image_height", "camera_matrix"):
        if key not in d:
            raise CameraInfoError(f"{source}: missing required field {key!r}")
    model = d.get("distortion_model", "plumb_bob")
    if not isinstance(model, str):
        raise CameraInfoError(f"{source}: distortion_model: expected a string, got {model!r}")
    D = _matrix(d, "distortion_coefficients", None, None, source) if "distortion_coefficients" in d else ()
    if not D:
        D = (0.0,) * DISTORTION_MODELS.get(model, 5)
    R = _matrix(d, "rectification_matrix", 3, 3, source) if "rectification_matrix" in d else _IDENTITY3
    P = _matrix(d, "projection_matrix", 3, 4, source) if "projection_matrix" in d else ()
    name = d.get("camera_name", "")
    return CameraInfoData(
        width=d["image_width"],
        height=d["image_height"],
        K=_matrix(d, "camera_matrix", 3, 3, source),
        distortion_model=model,
        D=D,
        R=R,
        P=P,
        camera_name=str(name) if name is not None else "",
        source=source,
    )


def load_camera_info(path: str | Path) -> CameraInfoData:
    """Load a ROS camera calibration YAML (duplicate keys and syntax errors raise :class:`CameraInfoError`)."""
    return camera_info_from_dict(load_strict(path, CameraInfoError), str(path))


def dump_camera_info(ci: CameraInfoData) -> str:
    """The YAML text of a calibration in the ROS format (matrices in flow style)."""
    d = ci.to_dict()
    lines = [
        f"image_width: {d['image_width']}",
        f"image_height: {d['image_height']}",
        f"camera_name: {d['camera_name']}",
    ]
    for key in ("camera_matrix",):
        lines += _dump_matrix(key, d[key])
    lines.append(f"distortion_model: {d['distortion_model']}")
    for key in ("distortion_coefficients", "rectification_matrix", "projection_matrix"):
        lines += _dump_matrix(key, d[key])
    return "\n".join(lines) + "\n"


def _dump_matrix(key: str, m: dict[str, Any]) -> list[str]:
    data = ", ".join(repr(float(v)) for v in m["data"])
    return [f"{key}:", f"  rows: {m['rows']}", f"  cols: {m['cols']}", f"  data: [{data}]"]


def save_camera_info(ci: CameraInfoData, path: str | Path) -> None:
    """Write a calibration in the ROS camera calibration YAML format."""
    Path(path).write_text(dump_camera_info(ci), encoding="utf-8")


# --------------------------------------------------------------------------------------------------------
# Distortion
# --------------------------------------------------------------------------------------------------------
def distort_normalized(xy: npt.ArrayLike, model: str, coefficients: npt.ArrayLike) -> FloatArray:
    """Apply a distortion model to normalised image coordinates (N, 2) → distorted normalised (N, 2)."""
    p = np.atleast_2d(np.asarray(xy, dtype=np.float64))
    d = np.asarray(coefficients, dtype=np.float64)
    x, y = p[:, 0], p[:, 1]
    r2 = x * x + y * y
    if model == "equidistant":
        k = np.zeros(4)
        k[: min(4, len(d))] = d[:4]
        r = np.sqrt(r2)
        th = np.arctan(r)
        th2 = th * th
        thd = th * (1.0 + th2 * (k[0] + th2 * (k[1] + th2 * (k[2] + th2 * k[3]))))
        with np.errstate(divide="ignore", invalid="ignore"):
            scale = np.where(r > 1e-12, thd / r, 1.0)
        return np.stack([x * scale, y * scale], -1)
    if model not in ("plumb_bob", "rational_polynomial"):
        raise ValueError(f"unsupported distortion model {model!r}")
    k = np.zeros(8)
    k[: min(8, len(d))] = d[:8]
    k1, k2, p1, p2, k3, k4, k5, k6 = k
    radial = (1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))) / (1.0 + r2 * (k4 + r2 * (k5 + r2 * k6)))
    xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
    yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
    return np.stack([xd, yd], -1)


def project(points_opt: npt.ArrayLike, ci: CameraInfoData) -> FloatArray:
    """Project optical-frame points (N, 3) to raw (distorted) pixels (N, 2); points behind give NaN."""
    P = np.atleast_2d(np.asarray(points_opt, dtype=np.float64))
    z = P[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        xy = P[:, :2] / z[:, None]
    xd = distort_normalized(xy, ci.distortion_model, ci.coefficients)
    out = np.stack([ci.fx * xd[:, 0] + ci.cx, ci.fy * xd[:, 1] + ci.cy], -1)
    out[z <= 0] = np.nan
    return out


def undistort_pixels(uv: npt.ArrayLike, ci: CameraInfoData) -> FloatArray:
    """Raw (distorted) pixels (N, 2) → ideal pinhole pixels (N, 2) in the same K (OpenCV, iterated to
    convergence). Without distortion the pixels are returned unchanged."""
    pts = np.atleast_2d(np.asarray(uv, dtype=np.float64))
    if not ci.has_distortion or len(pts) == 0:
        return pts.copy()
    import cv2  # lazy: configuration loading does not need OpenCV

    K = np.array(ci.K, dtype=np.float64).reshape(3, 3)
    src = np.ascontiguousarray(pts.reshape(-1, 1, 2))
    D = ci.coefficients
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
    if ci.distortion_model == "equidistant":
        try:
            out = cv2.fisheye.undistortPoints(src, K, D, R=np.eye(3), P=K, criteria=crit)
        except (TypeError, cv2.error):  # OpenCV without the criteria argument
            out = cv2.fisheye.undistortPoints(src, K, D, R=np.eye(3), P=K)
    elif hasattr(cv2, "undistortPointsIter"):  # OpenCV 4.x
        out = cv2.undistortPointsIter(src, K, D, np.eye(3), K, crit)
    else:  # OpenCV 5: undistortPoints takes the criteria
        out = cv2.undistortPoints(src, K, D, R=np.eye(3), P=K, criteria=crit)
    return np.asarray(out, dtype=np.float64).reshape(-1, 2)


def fill_camera_info_msg(msg: Any, ci: CameraInfoData) -> Any:
    """Copy a calibration into a ``sensor_msgs/CameraInfo``-like object (width, height, distortion_model,
    d, k, r, p); returns ``msg``. Duck-typed so it needs no ROS import."""
    msg.width, msg.height = int(ci.width), int(ci.height)
    msg.distortion_model = ci.distortion_model
    msg.d = [float(v) for v in ci.D]
    msg.k = [float(v) for v in ci.K]
    msg.r = [float(v) for v in ci.R]
    msg.p = [float(v) for v in ci.P]
    return msg
