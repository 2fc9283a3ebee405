"""Zoom optics and pinhole intrinsics (ROS-free, numpy only): zoom units ↔ magnification ↔ field of view, and
the intrinsics of a stream at a zoom.

Conventions (docs/conventions.md, geometry-and-calibration.md §3): VAPIX zoom units 1…9999 map to magnification
``m(z)`` through a per-camera monotone table (default: linear in magnification; each camera's HFOV and
magnification from its ``config/<model>.yaml``); ``HFOV = 2·atan(tan(HFOV_w/2)/m)``. Pinhole for a W×H stream:
``fx = (W/2)/tan(HFOV/2)``, ``fy = fx·(H/W)·image_aspect`` (4:3 analogue image for the 214, so PAL 704×576 has
fy = fx·12/11), ``cx = (W−1)/2``, ``cy = (H−1)/2``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum
from typing import Any

import numpy as np
import numpy.typing as npt

from axis_ptz_ros2.transforms import FloatArray


@dataclass(frozen=True, slots=True)
class Intrinsics:
    """Pinhole intrinsics of one stream (pixels). Distortion is not modelled (plumb_bob zeros)."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float

    @property
    def K(self) -> FloatArray:
        """3×3 camera matrix."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def hfov(self) -> float:
        """Horizontal field of view (rad) between the outer pixel edges."""
        return 2.0 * math.atan((self.width / 2.0) / self.fx)

    @property
    def vfov(self) -> float:
        """Vertical field of view (rad) between the outer pixel edges."""
        return 2.0 * math.atan((self.height / 2.0) / self.fy)

    def ray(self, u: npt.ArrayLike, v: npt.ArrayLike) -> FloatArray:
        """Unnormalised optical-frame rays ``(x, y, 1)`` through pixel coordinates (u right, v down)."""
        uu = np.asarray(u, dtype=np.float64)
        vv = np.asarray(v, dtype=np.float64)
        return np.stack([(uu - self.cx) / self.fx, (vv - self.cy) / self.fy, np.ones(np.broadcast(uu, vv).shape)], -1)

    def project(self, points_opt: npt.ArrayLike) -> FloatArray:
        """Project optical-frame points (N, 3) to pixels (N, 2); points behind the camera give NaN."""
        p = np.atleast_2d(np.asarray(points_opt, dtype=np.float64))
        z = p[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            u = self.fx * p[:, 0] / z + self.cx
            v = self.fy * p[:, 1] / z + self.cy
        out = np.stack([u, v], -1)
        out[z <= 0] = np.nan
        return out

    def scaled(self, width: int, height: int) -> Intrinsics:
        """The same optics for another stream size of the same sensor (resolution change)."""
        sx, sy = width / self.width, height / self.height
        return Intrinsics(width, height, self.fx * sx, self.fy * sy, (width - 1) / 2.0, (height - 1) / 2.0)


class ZoomCurve(StrEnum):
    """Shape of the zoom-units → magnification curve when no explicit table is configured."""

    LINEAR = "linear"  # m = 1 + (M−1)·t  (every published Axis zoomSteps table)
    LOG = "log"  # m = M**t


#: The fields a zoom model must be given (the optics); the others have neutral defaults (VAPIX 1…9999, linear
#: curve, a 4:3 frame, no digital zoom).
ZOOM_REQUIRED = ("hfov_wide_deg", "max_magnification")


@dataclass(frozen=True, slots=True)
class ZoomModel:
    """Zoom units ↔ magnification ↔ field of view for one camera model.

    ``table`` (optional) is a monotone list of ``(zoom_units, magnification)`` pairs (e.g. from a camera's
    ``zoomSteps`` attribute or a measurement); it is interpolated in log-magnification. Without a table the
    ``curve`` model with ``max_magnification`` at ``max_zoom`` is used.

    Digital zoom (modern Axis PTZ, ``PTZ.Support.S1.DigitalZoom=true``, ``MaxZoom=19999``): with
    ``optical_max_zoom`` set (e.g. 9999), the curve reaches ``max_magnification`` there and the units above it
    add ``digital_max_magnification``× linearly (vapix.md §8.3). Pixel aspect: ``square_pixels=False`` (the
    214) stretches the physical ``image_aspect`` frame onto any stream size (PAL 704×576 → fy = fx·12/11);
    ``square_pixels=True`` (a digital sensor of aspect ``image_aspect``) keeps fx = fy and uses the full
    width for streams at least as wide as the sensor, else the full height (sides cropped).
    """

    hfov_wide_deg: float  # no default: a camera model's optics come from its file (config/<model>.yaml)
    max_magnification: float
    min_zoom: int = 1
    max_zoom: int = 9999
    curve: ZoomCurve = ZoomCurve.LINEAR
    image_aspect: float = 4.0 / 3.0  # physical width/height of the full image (4:3 analogue for the 214)
    table: tuple[tuple[float, float], ...] = ()
    square_pixels: bool = False
    optical_max_zoom: int = 0  # 0: no digital zoom (max_zoom is the optical tele end)
    digital_max_magnification: float = 1.0

    def __post_init__(self) -> None:
        """Validate the configuration."""
        if self.optical_max_zoom and not self.min_zoom < self.optical_max_zoom <= self.max_zoom:
            raise ValueError("optical_max_zoom must lie in (min_zoom, max_zoom]")
        if self.digital_max_magnification < 1.0:
            raise ValueError(f"digital_max_magnification must be >= 1, got {self.digital_max_magnification}")
        if self.image_aspect <= 0.0:
            raise ValueError(f"image_aspect must be positive, got {self.image_aspect}")
        if not 0.0 < self.hfov_wide_deg < 180.0:
            raise ValueError(f"hfov_wide_deg must be in (0, 180), got {self.hfov_wide_deg}")
        if self.max_magnification < 1.0:
            raise ValueError(f"max_magnification must be >= 1, got {self.max_magnification}")
        if self.max_zoom <= self.min_zoom:
            raise ValueError("max_zoom must be greater than min_zoom")
        if self.table:
            zs = [z for z, _ in self.table]
            ms = [m for _, m in self.table]
            if any(b <= a for a, b in zip(zs, zs[1:], strict=False)) or any(
                b < a for a, b in zip(ms, ms[1:], strict=False)
            ):
                raise ValueError("zoom table must be strictly increasing in units and monotone in magnification")

    @staticmethod
    def from_dict(d: dict[str, Any]) -> ZoomModel:
        """Build from a configuration mapping (keys as the dataclass fields; ``table`` as [[z, m], ...])."""
        kw: dict[str, Any] = dict(d)
        missing = [k for k in ZOOM_REQUIRED if k not in kw]
        if missing:
            raise ValueError(f"missing key(s) {missing} (the optics: wide-end HFOV in degrees, tele magnification)")
        if "curve" in kw:
            kw["curve"] = ZoomCurve(kw["curve"])
        if "table" in kw:
            kw["table"] = tuple((float(z), float(m)) for z, m in kw["table"])
        return ZoomModel(**kw)

    def clamp(self, zoom: float) -> float:
        """Clamp zoom units into [min_zoom, max_zoom]."""
        return min(max(float(zoom), float(self.min_zoom)), float(self.max_zoom))

    def magnification(self, zoom: float) -> float:
        """Optical magnification at ``zoom`` units (1 at the wide end)."""
        z = self.clamp(zoom)
        if self.table:
            zs = np.array([p[0] for p in self.table])
            lm = np.log(np.array([p[1] for p in self.table]))
            return float(np.exp(np.interp(z, zs, lm)))
        zo = self._optical_end
        if z > zo:  # digital zoom: linear in magnification on top of the optical tele end
            return self.max_magnification * (
                1.0 + (self.digital_max_magnification - 1.0) * (z - zo) / (self.max_zoom - zo)
            )
        t = (z - self.min_zoom) / (zo - self.min_zoom)
        if self.curve is ZoomCurve.LOG:
            return float(self.max_magnification**t)
        return 1.0 + (self.max_magnification - 1.0) * t

    def zoom_for_magnification(self, magnification: float) -> float:
        """Inverse of :meth:`magnification` (zoom units, float; clamped to the range)."""
        m = min(max(magnification, self.magnification(self.min_zoom)), self.magnification(self.max_zoom))
        if self.table:
            zs = np.array([p[0] for p in self.table])
            lm = np.log(np.array([p[1] for p in self.table]))
            return float(np.interp(math.log(m), lm, zs))
        zo = self._optical_end
        if m > self.max_magnification and zo < self.max_zoom and self.digital_max_magnification > 1.0:
            frac = (m / self.max_magnification - 1.0) / (self.digital_max_magnification - 1.0)
            return zo + frac * (self.max_zoom - zo)
        if self.curve is ZoomCurve.LOG:
            t = math.log(m) / math.log(self.max_magnification) if self.max_magnification > 1 else 0.0
        else:
            t = (m - 1.0) / (self.max_magnification - 1.0) if self.max_magnification > 1 else 0.0
        return self.min_zoom + t * (zo - self.min_zoom)

    @property
    def _optical_end(self) -> int:
        """Zoom units of the optical tele end (``max_zoom`` without digital zoom)."""
        return self.optical_max_zoom if self.optical_max_zoom else self.max_zoom

    def hfov(self, zoom: float) -> float:
        """Horizontal field of view (rad) at ``zoom`` units."""
        half = math.tan(math.radians(self.hfov_wide_deg) / 2.0) / self.magnification(zoom)
        return 2.0 * math.atan(half)

    def zoom_for_hfov(self, hfov: float) -> float:
        """Zoom units that give a horizontal field of view of ``hfov`` radians (clamped)."""
        m = math.tan(math.radians(self.hfov_wide_deg) / 2.0) / math.tan(hfov / 2.0)
        return self.zoom_for_magnification(m)

    def intrinsics(self, zoom: float, width: int, height: int) -> Intrinsics:
        """Pinhole intrinsics of a ``width``×``height`` stream at ``zoom`` units."""
        half = math.tan(self.hfov(zoom) / 2.0)
        if self.square_pixels:
            if width / height >= self.image_aspect - 1e-9:
                fx = (width / 2.0) / half
            else:  # narrower than the sensor: full height, sides cropped
                fx = (height / 2.0) / (half / self.image_aspect)
            fy = fx
        else:
            fx = (width / 2.0) / half
            fy = fx * (height / width) * self.image_aspect
        return Intrinsics(width, height, fx, fy, (width - 1) / 2.0, (height - 1) / 2.0)
