"""The console's HTTP API as data (ROS-free): routes, the fields of every command, and bounded body parsing.

:data:`ROUTES` lists what the server answers (method, path, who may call it); :data:`COMMANDS` the JSON fields
of every ``POST /api/<command>`` with their type and accepted range. The same table drives the parsing here
(every number bounded before it is used, so nothing wraps in a uint32 message field or overflows a float),
the page's form limits (:func:`video_limits`, sent with the page's state) and the property-based tests in
``tests/fuzz`` (which generate values in, at and beyond every range). The video fields' ranges are the stream
node's parameter ranges, from the same constants.

Every refusal is a :class:`BadRequest` whose message names the field, what was wrong and what is accepted.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

from axis_ptz_ros2.streaming.limits import BUDGET_RANGE_KBPS
from axis_ptz_ros2.vapix.models import COMPRESSION_RANGE, FPS_RANGE

#: largest value of a ``uint32`` message field (image sizes of ``PixelTarget``)
UINT32_MAX = 2**32 - 1
#: zoom of the Axis PTZ heads in VAPIX units is 1..9999, so a relative zoom is within ±9998
MAX_ZOOM_DELTA = 9999.0
#: longest ``key`` / ``resolution`` string accepted
MAX_TEXT = 32
#: longest free-text note the page sends (the decoder's fallback reason)
MAX_NOTE = 200
#: largest counter the page reports (2**53: exact in a JavaScript number)
MAX_COUNT = 2**53


class BadRequest(ValueError):  # noqa: N818 - reads as the HTTP status
    """A request body the console cannot use (→ HTTP 400 with the reason)."""


@dataclass(frozen=True, slots=True)
class Field:
    """One JSON field of a command: its kind, accepted range and (when optional) the value meaning "keep"."""

    name: str
    kind: Literal["int", "float", "str"]
    lo: float = -math.inf
    hi: float = math.inf
    default: float | str | None = None  # None = required
    #: a value outside [lo, hi] that is accepted anyway (0 = keep fps, -1 = keep compression / budget)
    keep: float | None = None


@dataclass(frozen=True, slots=True)
class Route:
    """One route of the console: ``access`` is ``open`` (no token), ``page`` (login page when refused) or ``api``."""

    method: str
    path: str
    access: Literal["open", "page", "api"]
    description: str


STREAM_NAMES = ("ptz", "panorama", "overlay")

ROUTES: tuple[Route, ...] = (
    Route("GET", "/login", "open", "sign-in form"),
    Route("POST", "/login", "open", "sign in (form field token) → cookie"),
    Route("GET", "/", "page", "the console page"),
    Route("GET", "/index.html", "page", "the console page"),
    Route("GET", "/static/style.css", "open", "style sheet (also for the sign-in form)"),
    Route("GET", "/static/app.js", "api", "page script"),
    Route("GET", "/api/state", "api", "everything the page shows"),
    Route("GET", "/api/keymap", "api", "the keyboard teleop key map"),
    *(Route("GET", f"/video/{s}.mjpg", "api", f"{s} video (MJPEG)") for s in STREAM_NAMES),
    *(Route("GET", f"/video/{s}.jpg", "api", f"{s} snapshot (?fresh = wait for a new frame)") for s in STREAM_NAMES),
    Route("GET", "/video/ptz.h264", "api", "PTZ video as H.264 access units for WebCodecs (web/h264relay.py)"),
    Route("GET", "/video/still.jpg", "api", "the last full-quality still (404 until one has been taken)"),
    Route("POST", "/api/center", "api", "centre the PTZ view on a pixel"),
    Route("POST", "/api/look_panorama", "api", "look at a panorama pixel"),
    Route("POST", "/api/key", "api", "one keyboard teleop key"),
    Route("POST", "/api/video", "api", "video parameters and bandwidth budget"),
    Route("POST", "/api/home", "api", "go to the home position"),
    Route("POST", "/api/still", "api", "take a full-quality still (the stream node's still/capture)"),
    Route("POST", "/api/decoder", "api", "what the page's video decoder did (WebCodecs: frames, errors, codec)"),
)

_SIZE = (Field("width", "int", 1, UINT32_MAX), Field("height", "int", 1, UINT32_MAX))

#: the JSON fields of every command (unknown fields are ignored)
COMMANDS: dict[str, tuple[Field, ...]] = {
    "center": (
        Field("u", "float", 0.0),
        Field("v", "float", 0.0),
        *_SIZE,
        Field("zoom_delta", "float", -MAX_ZOOM_DELTA, MAX_ZOOM_DELTA, 0.0),
    ),
    "look_panorama": (Field("x", "float", 0.0), Field("y", "float", 0.0), *_SIZE),
    "key": (Field("key", "str", 1, MAX_TEXT),),
    "video": (
        # the stream node's parameter ranges (nodes/stream_params.py takes them from the same constants)
        Field("fps", "int", *FPS_RANGE, 0, keep=0),
        Field("resolution", "str", 0, MAX_TEXT, ""),
        Field("compression", "int", *COMPRESSION_RANGE, -1, keep=-1),
        Field("max_bitrate_kbps", "int", *BUDGET_RANGE_KBPS, -1, keep=-1),
    ),
    "home": (),
    "still": (),
    "decoder": (
        Field("mode", "str", 0, MAX_TEXT, ""),
        Field("decoded", "int", 0, MAX_COUNT, 0),
        Field("errors", "int", 0, MAX_COUNT, 0),
        Field("codec", "str", 0, MAX_TEXT, ""),
        Field("note", "str", 0, MAX_NOTE, ""),
    ),
}


def video_limits() -> dict[str, tuple[float, float]]:
    """The accepted range ``(lo, hi)`` of every number of ``POST /api/video``, for the page's form (which keeps no
    copy of them: ``GET /api/state`` carries them as ``limits``)."""
    return {f.name: (f.lo, f.hi) for f in COMMANDS["video"] if f.kind != "str"}


def _num(x: float) -> str:
    return str(int(x)) if math.isfinite(x) and x == int(x) and abs(x) < 1e16 else f"{x:g}"


def _accepted(f: Field) -> str:
    rng = f"{_num(f.lo)}..{_num(f.hi)}" if math.isfinite(f.hi) else f">= {_num(f.lo)}"
    return rng + (f" ({_num(f.keep)} = keep)" if f.keep is not None else "")


def number(body: dict[str, Any], key: str, default: float | None = None) -> float:
    """A finite number from a JSON body, or :class:`BadRequest` (never OverflowError: 400-digit integers)."""
    if key not in body or body[key] is None:
        if default is None:
            raise BadRequest(f"missing {key!r}")
        return default
    v = body[key]
    if isinstance(v, bool) or not isinstance(v, int | float):
        raise BadRequest(f"{key!r} must be a number, got {_short(v)}")
    try:
        f = float(v)
    except OverflowError:
        raise BadRequest(f"{key!r} is out of range") from None
    if not math.isfinite(f):
        raise BadRequest(f"{key!r} must be finite")
    return f


def integer(body: dict[str, Any], key: str, default: int | None = None) -> int:
    """An integer (JSON number without fraction) from a body, or :class:`BadRequest`."""
    v = body.get(key)
    if isinstance(v, int) and not isinstance(v, bool):
        return v  # exact: 2**32 + 352 stays itself, the range check sees it
    f = number(body, key, None if default is None else float(default))
    if f != int(f):
        raise BadRequest(f"{key!r} must be an integer, got {f!r}")
    return int(f)


def field_value(body: dict[str, Any], f: Field) -> float | str:
    """The value of field ``f`` in ``body``, type- and range-checked (:class:`BadRequest` otherwise)."""
    if f.kind == "str":
        raw = body.get(f.name)
        if raw is None or raw == "":
            if f.default is None:
                raise BadRequest(f"{f.name!r} must be a non-empty string")
            return str(f.default)
        if not isinstance(raw, str):
            raise BadRequest(f"{f.name!r} must be a string, got {_short(raw)}")
        if not (f.lo <= len(raw) <= f.hi):
            raise BadRequest(f"{f.name!r} must be at most {_num(f.hi)} characters")
        if not raw.isprintable():  # a NUL would silently cut the ROS string short; control keys have names
            raise BadRequest(f"{f.name!r} must be printable text, got {_short(raw)}")
        return raw
    dflt = f.default if isinstance(f.default, float | int) else None
    val: float = (
        integer(body, f.name, None if dflt is None else int(dflt)) if f.kind == "int" else number(body, f.name, dflt)
    )
    if val == f.keep or (dflt is not None and f.name not in body):
        return val
    if not (f.lo <= val <= f.hi):
        raise BadRequest(f"{f.name!r} = {_short(val)} is out of range: accepted {_accepted(f)}")
    return val


def parse(command: str, body: dict[str, Any]) -> dict[str, Any]:
    """Every field of ``command`` from ``body``, checked against :data:`COMMANDS`."""
    return {f.name: field_value(body, f) for f in COMMANDS[command]}


@dataclass(frozen=True, slots=True)
class PixelClick:
    """A click at (x, y) in an image of width × height pixels (all checked)."""

    x: float
    y: float
    width: int
    height: int


def pixel_click(body: dict[str, Any], xk: str, yk: str, what: str) -> PixelClick:
    """The pixel ``(body[xk], body[yk])`` of a ``width`` × ``height`` image; refuses a pixel outside it."""
    w = int(field_value(body, _SIZE[0]))
    h = int(field_value(body, _SIZE[1]))
    x, y = number(body, xk), number(body, yk)
    if not (0 <= x <= w and 0 <= y <= h):
        raise BadRequest(f"pixel ({x:g}, {y:g}) outside the {w}x{h} {what}")
    return PixelClick(x, y, w, h)


@dataclass(frozen=True, slots=True)
class CenterRequest:
    """``POST /api/center``: the pixel to bring to the centre, and a zoom change."""

    click: PixelClick
    zoom_delta: float


def center_request(body: dict[str, Any]) -> CenterRequest:
    """Parse and check ``POST /api/center``."""
    click = pixel_click(body, "u", "v", "image")
    zd = float(field_value(body, COMMANDS["center"][4]))
    return CenterRequest(click, zd)


def key_request(body: dict[str, Any]) -> str:
    """``POST /api/key``: the browser's ``KeyboardEvent.key`` (printable, at most :data:`MAX_TEXT` characters)."""
    return str(field_value(body, COMMANDS["key"][0]))


@dataclass(frozen=True, slots=True)
class VideoRequest:
    """``POST /api/video``: 0 / '' / -1 mean keep."""

    fps: int
    resolution: str
    compression: int
    max_bitrate_kbps: int

    @property
    def changes_stream(self) -> bool:
        """True when fps, resolution or compression change."""
        return bool(self.fps or self.resolution or self.compression >= 0)


def video_request(body: dict[str, Any]) -> VideoRequest:
    """Parse and check ``POST /api/video``; refuses a body that changes nothing."""
    v = parse("video", body)
    out = VideoRequest(int(v["fps"]), str(v["resolution"]), int(v["compression"]), int(v["max_bitrate_kbps"]))
    if not out.changes_stream and out.max_bitrate_kbps < 0:
        raise BadRequest("nothing to change")
    return out


def _short(v: object) -> str:
    text = repr(v)
    return text if len(text) <= 40 else text[:37] + "..."


@dataclass(frozen=True, slots=True)
class DecoderReport:
    """The page's video decoder report: mode (``h264`` / ``mjpeg``), cumulative decoded frames and decode errors
    of this page, the codec string, and why it fell back (if it did)."""

    mode: str
    decoded: int
    errors: int
    codec: str
    note: str


def decoder_request(body: dict[str, Any]) -> DecoderReport:
    """The ``decoder`` command's fields, checked."""
    v = parse("decoder", body)
    return DecoderReport(str(v["mode"]), int(v["decoded"]), int(v["errors"]), str(v["codec"]), str(v["note"]))
