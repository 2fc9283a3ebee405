"""Typed values of the VAPIX protocol and lenient parsers for the camera's ``key=value`` replies.

Implements the reply formats of reference ``vapix.md``: §4.4 (``query=position|limits|speed|
presetposcam``), §4.7 (``PTZ.Limit.L1`` / ``PTZ.Support.S1`` parameters), §5.1 and §5.5 (MJPEG
arguments, CIF resolution names, PAL/NTSC), §6 (param.cgi listings) and the parsing rules of §12:
strip, ignore lines without ``=``, accept ``\\r\\n``/``\\n``, an optional ``root.`` prefix,
``on/off``, ``yes/no``, ``true/false`` and floats with any number of decimals.

Units: angles are VAPIX degrees (+pan = right, +tilt = up); zoom/focus/iris are VAPIX units.
Conversion to REP-103 radians lives in :mod:`axis_ptz_ros2.geometry`, not here.
"""

from __future__ import annotations

import math
import re
from collections.abc import Collection, Mapping
from dataclasses import dataclass

from axis_ptz_ros2.vapix.errors import InvalidArgument, ResponseParseError

__all__ = [
    "CIF_NTSC",
    "CIF_PAL",
    "INT_RANGE",
    "MAX_IMAGE_SIDE",
    "DeviceInfo",
    "Preset",
    "PtzLimits",
    "PtzPosition",
    "Resolution",
    "VideoParams",
    "parse_bool",
    "parse_float",
    "parse_int",
    "parse_key_values",
    "strip_root",
]

# ---------------------------------------------------------------------------------------------
# Lenient key=value parsing (§12)
# ---------------------------------------------------------------------------------------------

_TRUE = frozenset({"on", "yes", "true", "1"})
_FALSE = frozenset({"off", "no", "false", "0"})


def strip_root(key: str) -> str:
    """Drop an optional leading ``root.`` (param.cgi echoes the requester's style, §6)."""
    return key[5:] if key.startswith("root.") else key


def parse_key_values(text: str) -> dict[str, str]:
    """Parse ``key=value`` lines: strip, skip lines without ``=``, drop ``root.``; last key wins."""
    result: dict[str, str] = {}
    for raw in text.splitlines():
        line = raw.strip()
        key, sep, value = line.partition("=")
        key = key.strip()
        if not sep or not key:
            continue
        result[strip_root(key)] = value.strip()
    return result


def parse_bool(value: str, *, key: str = "value") -> bool:
    """Parse ``on/off``, ``yes/no``, ``true/false``, ``1/0`` (case-insensitive)."""
    lowered = value.strip().lower()
    if lowered in _TRUE:
        return True
    if lowered in _FALSE:
        return False
    raise ResponseParseError(f"{key}: expected on/off, yes/no or true/false, got {value!r}")


def parse_float(value: str, *, key: str = "value") -> float:
    """Parse a finite float with any number of decimals (``51.2891``, ``-0.01``, ``10``)."""
    try:
        result = float(value.strip())
    except ValueError as err:
        raise ResponseParseError(f"{key}: expected a number, got {value!r}") from err
    if not math.isfinite(result):
        raise ResponseParseError(f"{key}: expected a finite number, got {value!r}")
    return result


INT_RANGE = (-(2**31), 2**31 - 1)
"""Integers a camera may report: VAPIX values are 32-bit (zoom, focus, iris, preset numbers, sizes). A larger
reply is refused here, never carried into a ROS message field where it would wrap or raise."""


def parse_int(value: str, *, key: str = "value") -> int:
    """Parse a 32-bit integer; a float form (``1.0``) is rounded to the nearest integer."""
    text = value.strip()
    if len(text) > 40:  # longer than any 32-bit value in any notation: refuse before int() does the work
        raise ResponseParseError(f"{key}: expected a 32-bit integer, got {len(text)} characters")
    try:
        result = int(text)
    except ValueError:
        result = round(parse_float(text, key=key))
    if not INT_RANGE[0] <= result <= INT_RANGE[1]:
        raise ResponseParseError(f"{key}: {text!r} outside the 32-bit range {INT_RANGE[0]}..{INT_RANGE[1]}")
    return result


def _opt(values: Mapping[str, str], key: str) -> str | None:
    value = values.get(key)
    return value if value not in (None, "") else None


def _req(values: Mapping[str, str], key: str, what: str) -> str:
    value = _opt(values, key)
    if value is None:
        raise ResponseParseError(f"{what}: reply has no {key!r} (keys: {sorted(values)})")
    return value


# ---------------------------------------------------------------------------------------------
# Resolutions (§5.5)
# ---------------------------------------------------------------------------------------------

CIF_PAL: Mapping[str, tuple[int, int]] = {
    "4CIF": (704, 576),
    "2CIFEXP": (704, 576),
    "2CIF": (704, 288),
    "CIF": (352, 288),
    "QCIF": (176, 144),
    "D1": (720, 576),
}
"""CIF names of a PAL analogue camera block (the Axis 214 PTZ); ``D1`` is the full ITU-R BT.601 frame."""

CIF_NTSC: Mapping[str, tuple[int, int]] = {
    "4CIF": (704, 480),
    "2CIFEXP": (704, 480),
    "2CIF": (704, 240),
    "CIF": (352, 240),
    "QCIF": (176, 120),
    "D1": (720, 480),
}
"""CIF names of an NTSC analogue camera block (e.g. the AXIS P5512 recording)."""

_WXH = re.compile(r"^\s*(\d{1,9})\s*[xX*]\s*(\d{1,9})\s*$")

MAX_IMAGE_SIDE = 16384
"""Largest width or height accepted from a camera or a user (16K; current Axis sensors stop at 8K). A size beyond
it is refused rather than carried into ``sensor_msgs`` uint32 fields (2^32 + 352 must never become 352)."""


@dataclass(frozen=True, slots=True)
class Resolution:
    """Image size in pixels; ``str()`` gives the wire form ``704x576``."""

    width: int
    height: int

    def __post_init__(self) -> None:
        """Refuse non-positive sizes."""
        if not (1 <= self.width <= MAX_IMAGE_SIDE and 1 <= self.height <= MAX_IMAGE_SIDE):
            raise InvalidArgument(f"resolution {self.width}x{self.height} outside 1..{MAX_IMAGE_SIDE} pixels per side")

    @classmethod
    def parse(cls, text: str, *, ntsc: bool = False) -> Resolution:
        """Parse ``704x576`` or a CIF name (``4CIF``, ``2CIFEXP``, ``2CIF``, ``CIF``, ``QCIF``, ``D1``)."""
        match = _WXH.match(text)
        if match is None and re.match(r"^\s*\d+\s*[xX*]\s*\d+\s*$", text):
            raise InvalidArgument(f"resolution {text.strip()!r} outside 1..{MAX_IMAGE_SIDE} pixels per side")
        if match:
            return cls(int(match.group(1)), int(match.group(2)))
        table = CIF_NTSC if ntsc else CIF_PAL
        size = table.get(text.strip().upper())
        if size is None:
            raise InvalidArgument(f"unknown resolution {text!r}: expected WxH or one of {', '.join(table)}")
        return cls(*size)

    def __str__(self) -> str:
        """Wire form, e.g. ``704x576``."""
        return f"{self.width}x{self.height}"


# ---------------------------------------------------------------------------------------------
# Video arguments (§5.1)
# ---------------------------------------------------------------------------------------------

FPS_RANGE = (1, 30)
COMPRESSION_RANGE = (0, 100)


@dataclass(frozen=True, slots=True)
class VideoParams:
    """Arguments of ``mjpg/video.cgi`` / ``jpg/image.cgi``: the documented ``fps`` (never ``req_fps``)."""

    resolution: Resolution
    fps: int
    compression: int
    camera: int = 1
    squarepixel: bool = False

    def validate(self, supported_resolutions: Collection[Resolution] | None = None) -> None:
        """Raise :class:`InvalidArgument` with the reason if the camera could not honour this.

        ``supported_resolutions`` is the camera's list (``Properties.Image.Resolution``); ``None``
        or an empty collection means "unknown" and skips that check.
        """
        if isinstance(self.fps, bool) or not isinstance(self.fps, int):
            raise InvalidArgument(f"fps must be an integer, got {self.fps!r}")
        if not FPS_RANGE[0] <= self.fps <= FPS_RANGE[1]:
            raise InvalidArgument(f"fps {self.fps} outside {FPS_RANGE[0]}..{FPS_RANGE[1]}")
        if isinstance(self.compression, bool) or not isinstance(self.compression, int):
            raise InvalidArgument(f"compression must be an integer, got {self.compression!r}")
        if not COMPRESSION_RANGE[0] <= self.compression <= COMPRESSION_RANGE[1]:
            raise InvalidArgument(
                f"compression {self.compression} outside {COMPRESSION_RANGE[0]}..{COMPRESSION_RANGE[1]}"
            )
        if self.camera < 1:
            raise InvalidArgument(f"camera must be >= 1, got {self.camera}")
        if supported_resolutions and self.resolution not in supported_resolutions:
            listed = ", ".join(str(r) for r in supported_resolutions)
            raise InvalidArgument(f"resolution {self.resolution} not supported by the camera (supported: {listed})")

    def query(self, *, include_fps: bool = True) -> dict[str, str]:
        """Query arguments in wire order; ``camera`` only when not 1 (§12), ``squarepixel=1`` if set."""
        args: dict[str, str] = {"resolution": str(self.resolution)}
        if include_fps:
            args["fps"] = str(self.fps)
        args["compression"] = str(self.compression)
        if self.camera != 1:
            args["camera"] = str(self.camera)
        if self.squarepixel:
            args["squarepixel"] = "1"
        return args


# ---------------------------------------------------------------------------------------------
# PTZ state (§4.4, §4.7)
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class PtzPosition:
    """Reply of ``query=position``; fields the camera does not report are ``None``."""

    pan_deg: float
    tilt_deg: float
    zoom: int
    focus: int | None = None
    iris: int | None = None
    brightness: int | None = None
    autofocus: bool | None = None
    autoiris: bool | None = None

    @classmethod
    def from_values(cls, values: Mapping[str, str]) -> PtzPosition:
        """Build from parsed ``key=value`` pairs; pan, tilt and zoom are required."""
        what = "query=position"

        def opt_int(key: str) -> int | None:
            value = _opt(values, key)
            return None if value is None else parse_int(value, key=key)

        def opt_bool(key: str) -> bool | None:
            value = _opt(values, key)
            return None if value is None else parse_bool(value, key=key)

        return cls(
            pan_deg=parse_float(_req(values, "pan", what), key="pan"),
            tilt_deg=parse_float(_req(values, "tilt", what), key="tilt"),
            zoom=parse_int(_req(values, "zoom", what), key="zoom"),
            focus=opt_int("focus"),
            iris=opt_int("iris"),
            brightness=opt_int("brightness"),
            autofocus=opt_bool("autofocus"),
            autoiris=opt_bool("autoiris"),
        )

    @classmethod
    def parse(cls, text: str) -> PtzPosition:
        """Parse the body of ``query=position``."""
        return cls.from_values(parse_key_values(text))


@dataclass(frozen=True, slots=True)
class PtzLimits:
    """Mechanical/optical limits (``query=limits`` or ``PTZ.Limit.L<n>``); field angles in degrees.

    On the wire ``MinFieldAngle``/``MaxFieldAngle`` are tenths of a degree (tele/wide HFOV).
    """

    min_pan_deg: float
    max_pan_deg: float
    min_tilt_deg: float
    max_tilt_deg: float
    min_zoom: int
    max_zoom: int
    min_focus: int | None = None
    max_focus: int | None = None
    min_iris: int | None = None
    max_iris: int | None = None
    min_field_angle_deg: float | None = None
    max_field_angle_deg: float | None = None

    @classmethod
    def from_values(cls, values: Mapping[str, str], *, prefix: str = "") -> PtzLimits:
        """Build from ``MinPan=…`` pairs; ``prefix`` selects e.g. ``PTZ.Limit.L1.``."""
        what = "PTZ limits"

        def req_f(key: str) -> float:
            return parse_float(_req(values, prefix + key, what), key=key)

        def req_i(key: str) -> int:
            return parse_int(_req(values, prefix + key, what), key=key)

        def opt_i(key: str) -> int | None:
            value = _opt(values, prefix + key)
            return None if value is None else parse_int(value, key=key)

        def opt_angle(key: str) -> float | None:
            value = _opt(values, prefix + key)
            return None if value is None else parse_float(value, key=key) / 10.0

        limits = cls(
            min_pan_deg=req_f("MinPan"),
            max_pan_deg=req_f("MaxPan"),
            min_tilt_deg=req_f("MinTilt"),
            max_tilt_deg=req_f("MaxTilt"),
            min_zoom=req_i("MinZoom"),
            max_zoom=req_i("MaxZoom"),
            min_focus=opt_i("MinFocus"),
            max_focus=opt_i("MaxFocus"),
            min_iris=opt_i("MinIris"),
            max_iris=opt_i("MaxIris"),
            min_field_angle_deg=opt_angle("MinFieldAngle"),
            max_field_angle_deg=opt_angle("MaxFieldAngle"),
        )
        if limits.min_pan_deg > limits.max_pan_deg or limits.min_tilt_deg > limits.max_tilt_deg:
            raise ResponseParseError(f"{what}: minimum above maximum in {limits}")
        if limits.min_zoom > limits.max_zoom:
            raise ResponseParseError(f"{what}: MinZoom above MaxZoom in {limits}")
        return limits

    @classmethod
    def parse(cls, text: str) -> PtzLimits:
        """Parse the body of ``query=limits``."""
        return cls.from_values(parse_key_values(text))

    @classmethod
    def from_params(cls, params: Mapping[str, str], *, camera: int = 1) -> PtzLimits:
        """Build from a ``param.cgi`` listing of group ``PTZ.Limit`` (``root.`` already stripped)."""
        return cls.from_values(params, prefix=f"PTZ.Limit.L{camera}.")


@dataclass(frozen=True, slots=True)
class Preset:
    """A server preset: ``presetposno<number>=<name>``."""

    number: int
    name: str

    @staticmethod
    def parse_list(text: str) -> tuple[Preset, ...]:
        """Parse ``query=presetposcam`` (header line ignored), sorted by number."""
        presets: list[Preset] = []
        for key, value in parse_key_values(text).items():
            if not key.lower().startswith("presetposno"):
                continue
            number_text = key[len("presetposno") :]
            if not number_text.isdigit():
                raise ResponseParseError(f"query=presetposcam: bad preset key {key!r}")
            presets.append(Preset(parse_int(number_text, key=key), value))
        return tuple(sorted(presets, key=lambda p: p.number))


@dataclass(frozen=True, slots=True)
class DeviceInfo:
    """What the driver needs to know about the camera (from ``Brand``/``Properties``/``PTZ.Support``)."""

    product: str
    firmware: str
    api_version: int | None
    resolutions: tuple[Resolution, ...]
    ptz: bool
    supports: frozenset[str]
