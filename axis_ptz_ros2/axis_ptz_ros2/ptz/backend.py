"""The PTZ backend protocol: what the ROS node needs from a pan-tilt-zoom head, in ROS units (ROS-free).

Every angle is REP-103 radians (``pan`` CCW/left positive about the PTZ base +z axis, ``tilt`` up positive),
zoom is in the camera's zoom units (VAPIX 1…9999 on the Axis 214), rates are rad/s. A backend raises
:class:`PtzBackendError` (only) for anything that went wrong talking to the head; the node turns it into a
service answer, a throttled log and a diagnostics counter.

Implementations: :class:`axis_ptz_ros2.ptz.axis_backend.AxisBackend` (VAPIX over HTTP); a virtual camera
implements the same protocol.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol, runtime_checkable


class PtzBackendError(Exception):
    """A backend could not do what was asked (camera unreachable, timed out, refused, bad reply)."""


class OutOfLimits(PtzBackendError):  # noqa: N818 - reads as a reason
    """A command lies outside the head's limits; it was not sent."""


@dataclass(frozen=True, slots=True)
class PtzLimitsRos:
    """Limits in ROS units: radians (REP-103) and zoom units. ``full_turn`` when pan wraps around freely."""

    pan_min: float
    pan_max: float
    tilt_min: float
    tilt_max: float
    zoom_min: float
    zoom_max: float

    @property
    def full_turn(self) -> bool:
        """Whether the pan range covers the whole circle (targets are then wrapped, not refused)."""
        return self.pan_max - self.pan_min >= 2.0 * math.pi - 1e-6

    def violation(self, pan: float | None, tilt: float | None, zoom: float | None, eps: float = 1e-9) -> str | None:
        """A human-readable reason if any given axis lies outside the limits, else None."""
        if pan is not None:
            if not math.isfinite(pan):
                return "pan is not finite"
            if not self.full_turn and not self.pan_min - eps <= pan <= self.pan_max + eps:
                return (
                    f"pan {math.degrees(pan):.3f} deg outside the limits "
                    f"{math.degrees(self.pan_min):.3f}..{math.degrees(self.pan_max):.3f} deg"
                )
        if tilt is not None:
            if not math.isfinite(tilt):
                return "tilt is not finite"
            if not self.tilt_min - eps <= tilt <= self.tilt_max + eps:
                return (
                    f"tilt {math.degrees(tilt):.3f} deg outside the limits "
                    f"{math.degrees(self.tilt_min):.3f}..{math.degrees(self.tilt_max):.3f} deg"
                )
        if zoom is not None:
            if not math.isfinite(zoom):
                return "zoom is not finite"
            if not self.zoom_min - 1e-6 <= zoom <= self.zoom_max + 1e-6:
                return f"zoom {zoom:g} outside the limits {self.zoom_min:g}..{self.zoom_max:g}"
        return None


@dataclass(frozen=True, slots=True)
class PtzReading:
    """One measured pose: radians (REP-103), zoom units, and when it was measured (wall-clock ns)."""

    pan: float
    tilt: float
    zoom: float
    stamp_ns: int


@dataclass(frozen=True, slots=True)
class PresetInfo:
    """A preset stored in the head."""

    number: int
    name: str


@runtime_checkable
class PtzBackend(Protocol):
    """A pan-tilt-zoom head in ROS units. Methods may block (HTTP); the node calls commands from one worker
    thread and :meth:`read_state` from its poll timer, possibly at the same time."""

    def limits(self) -> PtzLimitsRos:
        """The limits in effect (read from the head once, or a configured fallback)."""
        ...

    def read_state(self) -> PtzReading:
        """Measure the current pose."""
        ...

    def move_to(self, pan: float | None, tilt: float | None, zoom: float | None, speed: float | None = None) -> None:
        """Absolute move; None keeps an axis. ``speed`` is a 0..1 fraction of the maximum (None: default)."""
        ...

    def velocity(self, pan_rate: float, tilt_rate: float, zoom_rate: float) -> None:
        """Continuous motion: rad/s (clipped to the head's maximum), zoom −1..1; all zero stops."""
        ...

    def home(self) -> None:
        """Go to the home position."""
        ...

    def goto_preset(self, name: str) -> None:
        """Go to a stored preset."""
        ...

    def set_preset(self, name: str) -> None:
        """Store the current position under ``name``."""
        ...

    def remove_preset(self, name: str) -> None:
        """Delete a preset."""
        ...

    def list_presets(self) -> list[PresetInfo]:
        """Presets stored in the head, by number."""
        ...

    def close(self) -> None:
        """Release connections."""
        ...
