"""One small dataclass per PTZ call: it validates itself and builds its own query arguments.

Implements reference ``vapix.md`` §4.1 (``/axis-cgi/com/ptz.cgi`` arguments and their protocol
ranges), §4.2 (always send ``continuouspantiltmove=p,t`` explicitly so ``0,0`` stops), §4.6
(presets on ``/axis-cgi/com/ptzconfig.cgi``) and §12 ("clamp commands": here we *refuse*
anything outside the protocol range or the camera's :class:`~axis_ptz_ros2.vapix.models.PtzLimits`
before sending, so the driver never relies on the camera's silent clamping).

Units: VAPIX degrees (+pan = right, +tilt = up), floats sent with 4 decimals (never truncated).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from enum import StrEnum
from typing import ClassVar

from axis_ptz_ros2.vapix.errors import InvalidArgument
from axis_ptz_ros2.vapix.models import PtzLimits, PtzPosition

__all__ = [
    "PTZCONFIG_CGI",
    "PTZ_CGI",
    "AbsoluteMove",
    "AreaZoom",
    "Center",
    "ContinuousMove",
    "GotoPreset",
    "Move",
    "MoveDirection",
    "PtzQuery",
    "PtzRequest",
    "RelativeMove",
    "RemovePreset",
    "SetPreset",
    "SetSpeed",
    "format_float",
]

PTZ_CGI = "/axis-cgi/com/ptz.cgi"
PTZCONFIG_CGI = "/axis-cgi/com/ptzconfig.cgi"

# Protocol ranges (§4.1).
PAN_RANGE = (-180.0, 180.0)
TILT_RANGE = (-180.0, 180.0)
RPAN_RANGE = (-360.0, 360.0)
ZOOM_RANGE = (1, 19999)  # 9999 optical; up to 19999 with DigitalZoom
SPEED_RANGE = (1, 100)
VELOCITY_RANGE = (-100, 100)
_PRESET_FORBIDDEN = set('"<>~:')


class PtzQuery(StrEnum):
    """Values of ``ptz.cgi?query=`` (§4.4)."""

    POSITION = "position"
    LIMITS = "limits"
    SPEED = "speed"
    PRESETPOSCAM = "presetposcam"
    PRESETPOSALL = "presetposall"
    MODE = "mode"
    ATTRIBUTES = "attributes"


class MoveDirection(StrEnum):
    """Values of ``ptz.cgi?move=`` (§4.1)."""

    HOME = "home"
    UP = "up"
    DOWN = "down"
    LEFT = "left"
    RIGHT = "right"
    UPLEFT = "upleft"
    UPRIGHT = "upright"
    DOWNLEFT = "downleft"
    DOWNRIGHT = "downright"
    STOP = "stop"


def format_float(value: float) -> str:
    """4 decimals, sub-degree precision kept, ``-0.0000`` normalised to ``0.0000``."""
    text = f"{value:.4f}"
    return "0.0000" if text == "-0.0000" else text


def _finite(name: str, value: float) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise InvalidArgument(f"{name} must be a finite number, got {value!r}")
    return float(value)


def _integer(name: str, value: int | float) -> int:
    """Accept ints and integral floats (``3000.0``); refuse bools, fractions, NaN and others."""
    if isinstance(value, float) and value.is_integer():
        return int(value)
    if isinstance(value, bool) or not isinstance(value, int):
        raise InvalidArgument(f"{name} must be an integer, got {value!r}")
    return value


def _in_range(name: str, value: float, low: float, high: float, what: str = "protocol range") -> None:
    if not low <= value <= high:
        raise InvalidArgument(f"{name} {value:g} outside the {what} {low:g}..{high:g}")


def _zoom_range(limits: PtzLimits | None) -> tuple[int, int]:
    return (limits.min_zoom, limits.max_zoom) if limits is not None else (1, 9999)


class PtzRequest(ABC):
    """A ``ptz.cgi``/``ptzconfig.cgi`` command: ``path``, :meth:`validate`, :meth:`query`."""

    __slots__ = ()
    path: ClassVar[str] = PTZ_CGI

    def validate(self, limits: PtzLimits | None = None) -> None:  # noqa: B027 - optional hook
        """Raise :class:`InvalidArgument` if outside the protocol range or the camera's ``limits``."""

    @abstractmethod
    def query(self) -> dict[str, str]:
        """Query arguments (unencoded) for this command."""


@dataclass(frozen=True, slots=True)
class AbsoluteMove(PtzRequest):
    """``pan=<deg>&tilt=<deg>&zoom=<n>&speed=<1..100>``; omitted axes keep their position."""

    pan_deg: float | None = None
    tilt_deg: float | None = None
    zoom: int | None = None
    speed: int | None = None

    def validate(self, limits: PtzLimits | None = None) -> None:
        """Check protocol ranges and, with ``limits``, the camera's mechanical range."""
        if self.pan_deg is None and self.tilt_deg is None and self.zoom is None:
            raise InvalidArgument("absolute move needs at least one of pan, tilt, zoom")
        if self.pan_deg is not None:
            pan = _finite("pan", self.pan_deg)
            _in_range("pan", pan, *PAN_RANGE)
            if limits is not None:
                _in_range("pan", pan, limits.min_pan_deg, limits.max_pan_deg, "camera limits")
        if self.tilt_deg is not None:
            tilt = _finite("tilt", self.tilt_deg)
            _in_range("tilt", tilt, *TILT_RANGE)
            if limits is not None:
                _in_range("tilt", tilt, limits.min_tilt_deg, limits.max_tilt_deg, "camera limits")
        if self.zoom is not None:
            zoom = _integer("zoom", self.zoom)
            _in_range("zoom", zoom, *ZOOM_RANGE)
            if limits is not None:
                _in_range("zoom", zoom, limits.min_zoom, limits.max_zoom, "camera limits")
        if self.speed is not None:
            _in_range("speed", _integer("speed", self.speed), *SPEED_RANGE)

    def query(self) -> dict[str, str]:
        """``pan``/``tilt`` with 4 decimals, ``zoom``/``speed`` as integers."""
        args: dict[str, str] = {}
        if self.pan_deg is not None:
            args["pan"] = format_float(self.pan_deg)
        if self.tilt_deg is not None:
            args["tilt"] = format_float(self.tilt_deg)
        if self.zoom is not None:
            args["zoom"] = str(int(self.zoom))
        if self.speed is not None:
            args["speed"] = str(int(self.speed))
        return args


@dataclass(frozen=True, slots=True)
class RelativeMove(PtzRequest):
    """``rpan=<deg>&rtilt=<deg>&rzoom=<n>``; omitted axes do not move."""

    rpan_deg: float | None = None
    rtilt_deg: float | None = None
    rzoom: int | None = None

    def validate(self, limits: PtzLimits | None = None, *, current: PtzPosition | None = None) -> None:
        """Check protocol ranges; with ``limits`` and ``current`` also that the target is reachable."""
        if self.rpan_deg is None and self.rtilt_deg is None and self.rzoom is None:
            raise InvalidArgument("relative move needs at least one of rpan, rtilt, rzoom")
        max_zoom = limits.max_zoom if limits is not None else 9999
        if self.rpan_deg is not None:
            rpan = _finite("rpan", self.rpan_deg)
            _in_range("rpan", rpan, *RPAN_RANGE)
            if limits is not None and current is not None:
                _in_range(
                    "target pan",
                    current.pan_deg + rpan,
                    limits.min_pan_deg,
                    limits.max_pan_deg,
                    "camera limits",
                )
        if self.rtilt_deg is not None:
            rtilt = _finite("rtilt", self.rtilt_deg)
            _in_range("rtilt", rtilt, *RPAN_RANGE)
            if limits is not None and current is not None:
                _in_range(
                    "target tilt",
                    current.tilt_deg + rtilt,
                    limits.min_tilt_deg,
                    limits.max_tilt_deg,
                    "camera limits",
                )
        if self.rzoom is not None:
            rzoom = _integer("rzoom", self.rzoom)
            _in_range("rzoom", rzoom, -max_zoom, max_zoom)
            if limits is not None and current is not None:
                _in_range("target zoom", current.zoom + rzoom, limits.min_zoom, limits.max_zoom, "camera limits")

    def query(self) -> dict[str, str]:
        """``rpan``/``rtilt`` with 4 decimals, ``rzoom`` as integer."""
        args: dict[str, str] = {}
        if self.rpan_deg is not None:
            args["rpan"] = format_float(self.rpan_deg)
        if self.rtilt_deg is not None:
            args["rtilt"] = format_float(self.rtilt_deg)
        if self.rzoom is not None:
            args["rzoom"] = str(int(self.rzoom))
        return args


@dataclass(frozen=True, slots=True)
class ContinuousMove(PtzRequest):
    """``continuouspantiltmove=<p>,<t>[&continuouszoommove=<z>]``, −100..100; ``0,0`` stops (§4.2)."""

    pan_speed: int
    tilt_speed: int
    zoom_speed: int | None = None

    def validate(self, limits: PtzLimits | None = None) -> None:
        """Speeds must be integers in −100..100 (+pan right, +tilt up, +zoom in)."""
        _in_range("pan speed", _integer("pan speed", self.pan_speed), *VELOCITY_RANGE)
        _in_range("tilt speed", _integer("tilt speed", self.tilt_speed), *VELOCITY_RANGE)
        if self.zoom_speed is not None:
            _in_range("zoom speed", _integer("zoom speed", self.zoom_speed), *VELOCITY_RANGE)

    def query(self) -> dict[str, str]:
        """Pan/tilt velocity is always sent, even ``0,0`` (the TRADR stop bug, §4.2)."""
        args = {"continuouspantiltmove": f"{int(self.pan_speed)},{int(self.tilt_speed)}"}
        if self.zoom_speed is not None:
            args["continuouszoommove"] = str(int(self.zoom_speed))
        return args


def _check_pixel(x: int, y: int, width: int, height: int) -> tuple[int, int, int, int]:
    x = _integer("x", x)
    y = _integer("y", y)
    width = _integer("image width", width)
    height = _integer("image height", height)
    if width <= 0 or height <= 0:
        raise InvalidArgument(f"image size must be positive, got {width}x{height}")
    if not (0 <= x < width and 0 <= y < height):
        raise InvalidArgument(f"pixel ({x}, {y}) outside the {width}x{height} image")
    return x, y, width, height


@dataclass(frozen=True, slots=True)
class Center(PtzRequest):
    """``center=<x>,<y>&imagewidth=<w>&imageheight=<h>``: point the camera at a pixel (origin top-left)."""

    x: int
    y: int
    image_width: int
    image_height: int

    def validate(self, limits: PtzLimits | None = None) -> None:
        """The pixel must lie inside the image."""
        _check_pixel(self.x, self.y, self.image_width, self.image_height)

    def query(self) -> dict[str, str]:
        """Always sends the image size so the camera scales correctly."""
        return {
            "center": f"{int(self.x)},{int(self.y)}",
            "imagewidth": str(int(self.image_width)),
            "imageheight": str(int(self.image_height)),
        }


@dataclass(frozen=True, slots=True)
class AreaZoom(PtzRequest):
    """``areazoom=<x>,<y>,<z>``: center on a pixel and zoom the FOV by ``z/100`` (z ≥ 1)."""

    x: int
    y: int
    z: int
    image_width: int
    image_height: int

    def validate(self, limits: PtzLimits | None = None) -> None:
        """The pixel must lie inside the image and ``z`` must be ≥ 1 (100 = no zoom change)."""
        _check_pixel(self.x, self.y, self.image_width, self.image_height)
        if _integer("z", self.z) < 1:
            raise InvalidArgument(f"areazoom z must be >= 1 (100 keeps the zoom), got {self.z}")

    def query(self) -> dict[str, str]:
        """``areazoom`` plus the image size."""
        return {
            "areazoom": f"{int(self.x)},{int(self.y)},{int(self.z)}",
            "imagewidth": str(int(self.image_width)),
            "imageheight": str(int(self.image_height)),
        }


@dataclass(frozen=True, slots=True)
class Move(PtzRequest):
    """``move=<direction>`` (step move, ``home`` or ``stop``)."""

    direction: MoveDirection

    def validate(self, limits: PtzLimits | None = None) -> None:
        """The direction must be one of :class:`MoveDirection`."""
        try:
            MoveDirection(self.direction)
        except ValueError as err:
            raise InvalidArgument(f"unknown move direction {self.direction!r}") from err

    def query(self) -> dict[str, str]:
        """``move=<direction>``."""
        return {"move": str(MoveDirection(self.direction))}


def _check_preset_name(name: str) -> None:
    if not isinstance(name, str) or not name.strip():
        raise InvalidArgument("preset name must be a non-empty string")
    if len(name) > 31:
        raise InvalidArgument(f"preset name longer than 31 characters: {name!r}")
    bad = sorted(_PRESET_FORBIDDEN.intersection(name))
    if bad:
        raise InvalidArgument(f"preset name {name!r} contains forbidden characters {''.join(bad)!r}")


@dataclass(frozen=True, slots=True)
class GotoPreset(PtzRequest):
    """``gotoserverpresetname=<name>`` or ``gotoserverpresetno=<n>`` (exactly one)."""

    name: str | None = None
    number: int | None = None

    def validate(self, limits: PtzLimits | None = None) -> None:
        """Exactly one of ``name``/``number``; number ≥ 1."""
        if (self.name is None) == (self.number is None):
            raise InvalidArgument("goto preset needs exactly one of name or number")
        if self.name is not None:
            _check_preset_name(self.name)
        if self.number is not None and _integer("preset number", self.number) < 1:
            raise InvalidArgument(f"preset number must be >= 1, got {self.number}")

    def query(self) -> dict[str, str]:
        """By name when given, else by number."""
        if self.name is not None:
            return {"gotoserverpresetname": self.name}
        return {"gotoserverpresetno": str(self.number)}


@dataclass(frozen=True, slots=True)
class SetPreset(PtzRequest):
    """``ptzconfig.cgi?setserverpresetname=<name>[&home=yes]``: store the current position."""

    path: ClassVar[str] = PTZCONFIG_CGI
    name: str
    home: bool = False

    def validate(self, limits: PtzLimits | None = None) -> None:
        """Name ≤ 31 characters, none of ``"<>~:``."""
        _check_preset_name(self.name)

    def query(self) -> dict[str, str]:
        """``setserverpresetname`` (and ``home=yes`` to make it the home position)."""
        args = {"setserverpresetname": self.name}
        if self.home:
            args["home"] = "yes"
        return args


@dataclass(frozen=True, slots=True)
class RemovePreset(PtzRequest):
    """``ptzconfig.cgi?removeserverpresetname=<name>``."""

    path: ClassVar[str] = PTZCONFIG_CGI
    name: str

    def validate(self, limits: PtzLimits | None = None) -> None:
        """Name ≤ 31 characters, none of ``"<>~:``."""
        _check_preset_name(self.name)

    def query(self) -> dict[str, str]:
        """``removeserverpresetname=<name>``."""
        return {"removeserverpresetname": self.name}


@dataclass(frozen=True, slots=True)
class SetSpeed(PtzRequest):
    """``speed=<1..100>``: pan/tilt speed of later absolute/relative moves."""

    speed: int

    def validate(self, limits: PtzLimits | None = None) -> None:
        """1..100."""
        _in_range("speed", _integer("speed", self.speed), *SPEED_RANGE)

    def query(self) -> dict[str, str]:
        """``speed=<n>``."""
        return {"speed": str(int(self.speed))}
