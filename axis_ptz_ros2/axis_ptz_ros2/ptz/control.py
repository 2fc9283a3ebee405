"""Pointing glue in ROS units (ROS-free): the commanded target, relative accumulation, encoder offsets and the
centre / area-zoom / zoom / look-at set-points. All formulas come from :mod:`axis_ptz_ros2.geometry`; this
module only decides *which* pose to use and checks limits.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from axis_ptz_ros2.geometry import PtzKinematics, center_on_pixel, wrap_angle
from axis_ptz_ros2.optics import ZoomModel
from axis_ptz_ros2.ptz.backend import PtzLimitsRos, PtzReading
from axis_ptz_ros2.transforms import Transform


@dataclass(frozen=True, slots=True)
class Target:
    """A commanded pose; None = axis not commanded (unknown)."""

    pan: float | None = None
    tilt: float | None = None
    zoom: float | None = None

    @property
    def empty(self) -> bool:
        """No axis commanded."""
        return self.pan is None and self.tilt is None and self.zoom is None

    def commanded(self) -> dict[str, float]:
        """The commanded axes and their values (``pan``/``tilt`` rad, ``zoom`` units), the others left out."""
        return {
            axis: float(v) for axis, v in (("pan", self.pan), ("tilt", self.tilt), ("zoom", self.zoom)) if v is not None
        }

    def reached(self, r: PtzReading, tol_rad: float, tol_zoom: float) -> bool:
        """Every commanded axis is within tolerance of the reading."""
        return (
            (self.pan is None or abs(wrap_angle(r.pan - self.pan)) <= tol_rad)
            and (self.tilt is None or abs(r.tilt - self.tilt) <= tol_rad)
            and (self.zoom is None or abs(r.zoom - self.zoom) <= tol_zoom)
        )


@dataclass(frozen=True, slots=True)
class JointOffsets:
    """Encoder offsets of the calibrated mount: ``joint = head reading + offset`` (radians)."""

    pan: float = 0.0
    tilt: float = 0.0

    def from_head(self, r: PtzReading) -> PtzReading:
        """A head reading in joint coordinates."""
        if self.pan == 0.0 and self.tilt == 0.0:
            return r
        return PtzReading(r.pan + self.pan, r.tilt + self.tilt, r.zoom, r.stamp_ns)

    def to_head(self, pan: float | None, tilt: float | None) -> tuple[float | None, float | None]:
        """Joint set-points as head set-points."""
        return (None if pan is None else pan - self.pan), (None if tilt is None else tilt - self.tilt)

    def limits(self, lim: PtzLimitsRos) -> PtzLimitsRos:
        """Head limits in joint coordinates."""
        return PtzLimitsRos(
            lim.pan_min + self.pan,
            lim.pan_max + self.pan,
            lim.tilt_min + self.tilt,
            lim.tilt_max + self.tilt,
            lim.zoom_min,
            lim.zoom_max,
        )


def merge_target(
    previous: Target | None,
    reading: PtzReading | None,
    pan: float | None,
    tilt: float | None,
    zoom: float | None,
    relative: bool,
) -> Target:
    """The new full target of an absolute or relative command.

    Absolute: given axes replace, the others keep the previous target (or stay uncommanded). Relative: the
    offset is added to the previous *target* of that axis (so a burst of small steps adds up exactly, however
    far the head lags), or to the measured pose when that axis has no target. Raises ValueError when a
    relative axis has neither.
    """
    prev = previous or Target()
    out = [prev.pan, prev.tilt, prev.zoom]
    measured = (reading.pan, reading.tilt, reading.zoom) if reading is not None else (None, None, None)
    for i, (value, name) in enumerate(((pan, "pan"), (tilt, "tilt"), (zoom, "zoom"))):
        if value is None:
            continue
        if not relative:
            out[i] = value
            continue
        base = out[i] if out[i] is not None else measured[i]
        if base is None:
            raise ValueError(f"relative {name}: the current pose is not known yet")
        out[i] = base + value
    return Target(out[0], out[1], out[2])


def normalize_target(t: Target, lim: PtzLimitsRos) -> Target:
    """Wrap pan into (−π, π] on a head that turns freely; others unchanged."""
    if t.pan is not None and lim.full_turn:
        return Target(wrap_angle(t.pan), t.tilt, t.zoom)
    return t


def center_target(
    reading: PtzReading, u: float, v: float, width: int, height: int, zoom_model: ZoomModel
) -> tuple[float, float]:
    """(pan, tilt) that brings pixel (u, v) of a ``width``×``height`` image taken at ``reading`` to the image
    centre, exact at any tilt (zoom-correct intrinsics)."""
    intr = zoom_model.intrinsics(reading.zoom, width, height)
    return center_on_pixel(reading.pan, reading.tilt, u, v, intr)


def area_zoom_target(
    reading: PtzReading,
    box: tuple[float, float, float, float],
    width: int,
    height: int,
    zoom_model: ZoomModel,
) -> tuple[float, float, float]:
    """Centre on the box ``(u_min, v_min, u_max, v_max)`` and zoom so it fills the view (the larger of its
    relative width/height fills that dimension). Returns (pan, tilt, zoom units, clamped to the model)."""
    u0, v0, u1, v1 = box
    bw, bh = abs(u1 - u0), abs(v1 - v0)
    if bw <= 0.0 or bh <= 0.0:
        raise ValueError("the box must have a positive width and height")
    pan, tilt = center_target(reading, (u0 + u1) / 2.0, (v0 + v1) / 2.0, width, height, zoom_model)
    factor = min(width / bw, height / bh)  # a pinhole's magnification scales 1/tan(fov/2) linearly
    m = zoom_model.magnification(reading.zoom) * factor
    return pan, tilt, zoom_model.zoom_for_magnification(m)


def zoom_target(zoom_model: ZoomModel, zoom: float | None, magnification: float | None, hfov: float | None) -> float:
    """Zoom units from exactly one of units, magnification or horizontal FOV (rad)."""
    given = [x is not None for x in (zoom, magnification, hfov)]
    if sum(given) != 1:
        raise ValueError("set exactly one of zoom, magnification, hfov (the others NaN)")
    if zoom is not None:
        return zoom
    if magnification is not None:
        lo, hi = zoom_model.magnification(zoom_model.min_zoom), zoom_model.magnification(zoom_model.max_zoom)
        if not lo - 1e-9 <= magnification <= hi + 1e-9:
            raise ValueError(f"magnification {magnification:g} outside {lo:g}..{hi:g}")
        return zoom_model.zoom_for_magnification(magnification)
    assert hfov is not None
    lo, hi = zoom_model.hfov(zoom_model.max_zoom), zoom_model.hfov(zoom_model.min_zoom)
    if not lo - 1e-9 <= hfov <= hi + 1e-9:
        raise ValueError(
            f"hfov {math.degrees(hfov):.3f} deg outside {math.degrees(lo):.3f}..{math.degrees(hi):.3f} deg"
        )
    return zoom_model.zoom_for_hfov(hfov)


def look_at_target(
    point: npt.ArrayLike,
    frame: str,
    ptz_base_frame: str,
    mount_parent_frame: str,
    T_parent_ptzbase: Transform,
    kinematics: PtzKinematics,
) -> tuple[float, float]:
    """(pan, tilt) that puts ``point`` (in ``frame``: the PTZ base or the mount's parent frame) on the optical
    axis, with exact parallax (the optical centre is not at the frame origin)."""
    p = np.asarray(point, dtype=np.float64)
    if frame in ("", ptz_base_frame):
        p_base = p
    elif frame == mount_parent_frame:
        p_base = T_parent_ptzbase.inverse().apply(p)
    else:
        raise ValueError(f"unknown frame {frame!r}: give the point in {ptz_base_frame!r} or {mount_parent_frame!r}")
    if not np.all(np.isfinite(p_base)):
        raise ValueError("the point is not finite")
    return kinematics.look_at(p_base)


def clamp_zoom(zoom: float, lim: PtzLimitsRos) -> float:
    """``zoom`` within the head's zoom range."""
    return min(max(zoom, lim.zoom_min), lim.zoom_max)


def pixel_center_target(
    reading: PtzReading | None,
    u: float,
    v: float,
    width: int,
    height: int,
    zoom_model: ZoomModel,
    zoom_delta: float,
    lim: PtzLimitsRos,
) -> tuple[float, float, float | None]:
    """A centre-on-pixel command checked: (pan, tilt, zoom or None). The pixel must lie inside the image; a
    finite non-zero ``zoom_delta`` is added to the current zoom, clamped to the head's range (NaN or 0: zoom
    unchanged). Raises ValueError with the reason of a refusal."""
    if math.isinf(zoom_delta):
        raise ValueError("zoom_delta is infinite")
    if reading is None:
        raise ValueError("the current pose is not known yet")
    if not (math.isfinite(u) and math.isfinite(v) and 0.0 <= u <= width - 1 and 0.0 <= v <= height - 1):
        raise ValueError(f"pixel ({u:g}, {v:g}) outside the {width}x{height} image")
    with np.errstate(all="ignore"):  # an absurd image size must give a refusal, not a numpy warning
        pan, tilt = center_target(reading, u, v, width, height, zoom_model)
    if not (math.isfinite(pan) and math.isfinite(tilt)):
        raise ValueError(f"pixel ({u:g}, {v:g}) of a {width}x{height} image gives no finite pose")
    zoom = None
    if math.isfinite(zoom_delta) and zoom_delta != 0.0:
        zoom = clamp_zoom(reading.zoom + zoom_delta, lim)
    return pan, tilt, zoom


def area_zoom_command(
    reading: PtzReading | None,
    box: tuple[float, float, float, float],
    width: int,
    height: int,
    zoom_model: ZoomModel,
    lim: PtzLimitsRos,
) -> tuple[float, float, float]:
    """An area-zoom command checked: :func:`area_zoom_target` with the zoom clamped to the head's range.
    Raises ValueError with the reason of a refusal (pose unknown, box not finite, empty or centred outside the
    image, or no finite pose from it)."""
    if reading is None:
        raise ValueError("the current pose is not known yet")
    if not all(math.isfinite(b) for b in box):
        raise ValueError("the box is not finite")
    u0, v0, u1, v1 = box
    if not (min(u0, u1) >= 0.0 and max(u0, u1) <= width and min(v0, v1) >= 0.0 and max(v0, v1) <= height):
        raise ValueError(f"the box ({u0:g}, {v0:g})-({u1:g}, {v1:g}) is not inside the {width}x{height} image")
    with np.errstate(all="ignore"):  # a degenerate box must give a refusal, not a numpy warning
        pan, tilt, zoom = area_zoom_target(reading, box, width, height, zoom_model)
    if not all(math.isfinite(x) for x in (pan, tilt, zoom)):
        raise ValueError(f"the box {box} of a {width}x{height} image gives no finite pose")
    return pan, tilt, clamp_zoom(zoom, lim)
