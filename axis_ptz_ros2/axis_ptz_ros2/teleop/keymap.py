"""The keyboard teleop's key map (thesis §3.4.4, Table 5.3) as pure data and pure functions (ROS-free).

Keys → :class:`Action` (``KEYMAP``); :func:`apply` turns one key and the current :class:`TeleopState` into
ROS-free commands plus the new state. ``keyboard.py`` only reads the terminal, calls :func:`apply` and sends
the commands over ROS interfaces.

The quality keys Y/H follow the stream's codec (``video/params``' ``codec``): with MJPEG they step the JPEG
compression; with H.264 they step the bitrate through :data:`BITRATE_STEPS_KBPS`, the bitrate without feedback
(``h264_bitrate_kbps``) and the ceiling a clear link may raise it to (``h264_max_bitrate_kbps``) together, so the
key acts whether or not the viewer reports on the link. R/F and T/G act the same with both codecs (what the
camera is asked for; the H.264 encoder follows).

Sign convention: the thesis writes the pan keys in Axis terms ("A: turn by −x° in pan axis",
Axis +pan = right) on an upright Axis 214 whose VAPIX pan is clockwise. Its intent — A turns the view
left, D right, W up, S down — is kept for every camera by emitting REP-103 offsets (``PtzCommand``: pan
CCW/left positive, tilt up positive): A = +x°, D = −x°, W = +x°, S = −x°. On the Axis 214 convention this
is exactly the thesis's −x° VAPIX pan for A (``VapixConvention().to_vapix``, checked in the unit tests);
the PTZ node does the VAPIX conversion for other conventions (ceiling mount, ccw pan), so the view still
turns the way the key says.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from enum import StrEnum
from types import MappingProxyType
from typing import Any

from axis_ptz_ros2.streaming.budget import AXIS214_PAL_RESOLUTIONS
from axis_ptz_ros2.vapix.models import COMPRESSION_RANGE, FPS_RANGE  # R/F and Y/H stop at the camera's ends

FPS_STEP = 3  #: R/F change the frame rate by this many frames per second
COMPRESSION_STEP = 10  #: Y/H change the JPEG compression by this much (MJPEG)
#: kbit/s: Y/H walk the H.264 bitrates through these (H.264), a value between two moves to the next one; the ends
#: are the stream node's range (:data:`~axis_ptz_ros2.media.limits.BITRATE_RANGE_KBPS`, checked by a test)
BITRATE_STEPS_KBPS: tuple[int, ...] = (
    100, 150, 200, 300, 400, 500, 700, 1000, 1500, 2000, 3000, 4000, 5000, 7000, 10000, 15000, 20000
)  # fmt: skip
FAST_FACTOR = 5  #: SHIFT multiplies pan/tilt steps by this
ZOOM_UNITS_PER_STEP = 10  #: Q/E zoom by this many VAPIX units per step-size unit
FAST_ZOOM_UNITS_PER_STEP = 100  #: SHIFT+Q/E
#: Axis 214 PAL stream sizes (4CIF/2CIFEXP, 2CIF, CIF, QCIF; vapix.md §5.5), smallest first, used until the
#: stream node says otherwise (the stream node's own fallback list, ``streaming.budget``).
DEFAULT_RESOLUTIONS: tuple[str, ...] = tuple(
    str(r) for r in sorted(AXIS214_PAL_RESOLUTIONS, key=lambda r: (r.width * r.height, r.width))
)

CTRL_C = "\x03"
CTRL_Q = "\x11"
ESC = "\x1b"


class Kind(StrEnum):
    """What a key does."""

    PAN = "pan"
    TILT = "tilt"
    ZOOM = "zoom"
    STEP = "step"
    HOME = "home"
    FPS = "fps"
    RESOLUTION = "resolution"
    COMPRESSION = "compression"
    STOP = "stop"
    STILL = "still"
    HELP = "help"
    QUIT = "quit"


@dataclass(frozen=True, slots=True)
class Action:
    """One entry of the key map: ``sign`` is the direction (REP-103 for pan/tilt, + = zoom in / more),
    ``fast`` the SHIFT variant, ``value`` the digit of a step-size key."""

    kind: Kind
    sign: int = 0
    fast: bool = False
    value: int = 0
    description: str = ""


def _km() -> dict[str, Action]:
    m: dict[str, Action] = {}
    for key, kind, sign, what in (
        ("a", Kind.PAN, +1, "turn left by x deg (thesis: pan -x deg)"),
        ("d", Kind.PAN, -1, "turn right by x deg (thesis: pan +x deg)"),
        ("w", Kind.TILT, +1, "tilt up by x deg"),
        ("s", Kind.TILT, -1, "tilt down by x deg"),
    ):
        m[key] = Action(kind, sign, False, 0, what)
        fast = what.replace("by x", f"by {FAST_FACTOR}*x").replace("x deg)", f"{FAST_FACTOR}*x deg)")
        m[key.upper()] = Action(kind, sign, True, 0, fast)
    m["q"] = Action(Kind.ZOOM, -1, False, 0, f"zoom out by {ZOOM_UNITS_PER_STEP}*x units")
    m["e"] = Action(Kind.ZOOM, +1, False, 0, f"zoom in by {ZOOM_UNITS_PER_STEP}*x units")
    m["Q"] = Action(Kind.ZOOM, -1, True, 0, f"zoom out by {FAST_ZOOM_UNITS_PER_STEP}*x units")
    m["E"] = Action(Kind.ZOOM, +1, True, 0, f"zoom in by {FAST_ZOOM_UNITS_PER_STEP}*x units")
    for d in range(1, 10):
        m[str(d)] = Action(Kind.STEP, 0, False, d, f"step size x = {d}")
    m[" "] = Action(Kind.HOME, description="go to the home position")
    # Video keys: the thesis has no SHIFT variants; the upper case does the same (Caps Lock safe).
    for key, kind, sign, what in (
        ("r", Kind.FPS, +1, f"fps +{FPS_STEP}"),
        ("f", Kind.FPS, -1, f"fps -{FPS_STEP}"),
        ("t", Kind.RESOLUTION, +1, "higher resolution"),
        ("g", Kind.RESOLUTION, -1, "lower resolution"),
        ("y", Kind.COMPRESSION, +1, f"MJPEG: compression +{COMPRESSION_STEP}; H.264: bitrate one step down"),
        ("h", Kind.COMPRESSION, -1, f"MJPEG: compression -{COMPRESSION_STEP}; H.264: bitrate one step up"),
    ):
        m[key] = Action(kind, sign, False, 0, what)
        m[key.upper()] = Action(kind, sign, False, 0, what)
    # Arrow keys (decoded by split_keys) do what A/D/W/S do.
    m["<left>"] = replace(m["a"], description="turn left by x deg")
    m["<right>"] = replace(m["d"], description="turn right by x deg")
    m["<up>"] = replace(m["w"], description="tilt up by x deg")
    m["<down>"] = replace(m["s"], description="tilt down by x deg")
    # P(icture): a full-quality still (the stream node's still/capture: compression 0 at the camera's full size)
    m["p"] = Action(Kind.STILL, description="take a full-quality still (still/capture -> still/compressed)")
    m["P"] = m["p"]
    m["x"] = Action(Kind.STOP, description="stop any motion")
    m["X"] = m["x"]
    m[ESC] = m["x"]
    m["?"] = Action(Kind.HELP, description="show / hide this help")
    m[CTRL_C] = Action(Kind.QUIT, description="quit")
    m[CTRL_Q] = Action(Kind.QUIT, description="quit")
    return m


#: The key map. Keys are single characters as read from a raw terminal, or ``<left>``/``<right>``/``<up>``/
#: ``<down>`` for the arrow keys (see :func:`split_keys`).
KEYMAP: Mapping[str, Action] = MappingProxyType(_km())


# --------------------------------------------------------------------------------------------------------
# Commands (what the teleop has to send; ROS-free)
# --------------------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class RelativeMove:
    """A relative PTZ move, REP-103 (rad, CCW/up positive) and VAPIX zoom units; NaN = axis unchanged."""

    pan: float = math.nan
    tilt: float = math.nan
    zoom: float = math.nan


@dataclass(frozen=True, slots=True)
class GoHome:
    """Go to the home position (``ptz/home``)."""


@dataclass(frozen=True, slots=True)
class StopMotion:
    """Stop now (zero velocity)."""


@dataclass(frozen=True, slots=True)
class SetVideo:
    """New video parameters (SetVideoParams semantics: fps 0 = keep, resolution "" = keep, compression −1 =
    keep, the H.264 bitrates 0 = keep)."""

    fps: int = 0
    resolution: str = ""
    compression: int = -1
    h264_bitrate_kbps: int = 0
    h264_max_bitrate_kbps: int = 0


@dataclass(frozen=True, slots=True)
class TakeStill:
    """Take a full-quality still (the stream node's ``still/capture``; it arrives on ``still/compressed``)."""


@dataclass(frozen=True, slots=True)
class ToggleHelp:
    """Show or hide the help screen."""


@dataclass(frozen=True, slots=True)
class Quit:
    """End the program."""


@dataclass(frozen=True, slots=True)
class Notice:
    """A message for the operator (nothing is sent)."""

    text: str


Command = RelativeMove | GoHome | StopMotion | SetVideo | TakeStill | ToggleHelp | Quit | Notice


@dataclass(frozen=True, slots=True)
class TeleopState:
    """What the teleop knows: the step size x and the video parameters in effect (None = not known yet).

    The video values are those last reported by the stream node (``video/params``); :func:`apply` only
    computes the next request from them, it does not assume the request succeeds.
    """

    step: int = 1
    fps: int | None = None
    resolution: str | None = None
    compression: int | None = None
    resolutions: tuple[str, ...] = field(default=DEFAULT_RESOLUTIONS)
    codec: str = "mjpeg"  # what Y/H act on: "mjpeg" (compression) or "h264" (bitrate)
    h264_bitrate_kbps: int | None = None  # without feedback
    h264_max_bitrate_kbps: int | None = None  # the ceiling with feedback


def parse_resolution(text: str) -> tuple[int, int]:
    """``"704x576"`` → ``(704, 576)``; ValueError for anything else."""
    w, sep, h = text.strip().lower().partition("x")
    if not sep:
        raise ValueError(f"not a WIDTHxHEIGHT resolution: {text!r}")
    width, height = int(w), int(h)
    if width <= 0 or height <= 0:
        raise ValueError(f"not a positive resolution: {text!r}")
    return width, height


def sort_resolutions(resolutions: Sequence[str]) -> tuple[str, ...]:
    """Unique WxH strings ordered by pixel count, then width (unparseable entries are dropped)."""
    out: dict[tuple[int, int, int], str] = {}
    for r in resolutions:
        try:
            w, h = parse_resolution(r)
        except ValueError:
            continue
        out.setdefault((w * h, w, h), f"{w}x{h}")
    return tuple(out[k] for k in sorted(out))


def with_video(state: TeleopState, msg: Any) -> TeleopState:  # noqa: ANN401 - a VideoParams message
    """``state`` after the stream node's ``video/params`` (``axis_ptz_interfaces/VideoParams``): the values in effect,
    the camera's own resolution list when it sends one (else the list ``state`` had), and what Y/H act on (the JPEG
    compression, or the H.264 bitrates when ``codec`` is ``h264``)."""
    listed = sort_resolutions(list(msg.available_resolutions)) if msg.available_resolutions else ()
    return replace(
        state,
        fps=int(msg.fps),
        resolution=str(msg.resolution) or f"{msg.width}x{msg.height}",
        compression=int(msg.compression),
        resolutions=listed or state.resolutions,
        codec="h264" if msg.codec == "h264" else "mjpeg",
        h264_bitrate_kbps=int(msg.h264_bitrate_kbps) or None,
        h264_max_bitrate_kbps=int(msg.h264_max_bitrate_kbps) or None,
    )


def next_resolution(current: str, resolutions: Sequence[str], direction: int) -> str | None:
    """The next larger (``direction`` > 0) or smaller resolution of the list; None at the end of the list.

    A current value not in the list moves to the nearest list entry in that direction.
    """
    ordered = sort_resolutions(resolutions)
    if not ordered:
        return None
    w, h = parse_resolution(current)
    key = (w * h, w)
    keys = [(a * b, a) for a, b in (parse_resolution(r) for r in ordered)]
    if direction > 0:
        bigger = [r for k, r in zip(keys, ordered, strict=True) if k > key]
        return bigger[0] if bigger else None
    smaller = [r for k, r in zip(keys, ordered, strict=True) if k < key]
    return smaller[-1] if smaller else None


def _clamp(v: int, lo_hi: tuple[int, int]) -> int:
    return max(lo_hi[0], min(lo_hi[1], v))


def apply(key: str, state: TeleopState) -> tuple[list[Command], TeleopState]:
    """One key press: the commands to send and the new state. Unknown keys do nothing."""
    action = KEYMAP.get(key)
    if action is None:
        return [], state
    k = action.kind
    x = state.step
    if k is Kind.PAN:
        deg = x * (FAST_FACTOR if action.fast else 1)
        return [RelativeMove(pan=action.sign * math.radians(deg))], state
    if k is Kind.TILT:
        deg = x * (FAST_FACTOR if action.fast else 1)
        return [RelativeMove(tilt=action.sign * math.radians(deg))], state
    if k is Kind.ZOOM:
        units = x * (FAST_ZOOM_UNITS_PER_STEP if action.fast else ZOOM_UNITS_PER_STEP)
        return [RelativeMove(zoom=float(action.sign * units))], state
    if k is Kind.STEP:
        return [], replace(state, step=action.value)
    if k is Kind.HOME:
        return [GoHome()], state
    if k is Kind.STOP:
        return [StopMotion()], state
    if k is Kind.STILL:
        return [TakeStill()], state
    if k is Kind.HELP:
        return [ToggleHelp()], state
    if k is Kind.QUIT:
        return [StopMotion(), Quit()], state
    if k is Kind.FPS:
        if state.fps is None:
            return [Notice("frame rate not known yet (no video/params)")], state
        fps = _clamp(state.fps + action.sign * FPS_STEP, FPS_RANGE)
        if fps == state.fps:
            return [Notice(f"fps already at its limit ({fps})")], state
        return [SetVideo(fps=fps)], state
    if k is Kind.COMPRESSION and state.codec == "h264":
        return _bitrate_key(-action.sign, state), state  # compression + = smaller = a lower bitrate
    if k is Kind.COMPRESSION:
        if state.compression is None:
            return [Notice("compression not known yet (no video/params)")], state
        c = _clamp(state.compression + action.sign * COMPRESSION_STEP, COMPRESSION_RANGE)
        if c == state.compression:
            return [Notice(f"compression already at its limit ({c})")], state
        return [SetVideo(compression=c)], state
    # Kind.RESOLUTION
    if state.resolution is None:
        return [Notice("resolution not known yet (no video/params)")], state
    try:
        res = next_resolution(state.resolution, state.resolutions, action.sign)
    except ValueError:
        return [Notice(f"cannot parse the current resolution {state.resolution!r}")], state
    if res is None:
        end = "top" if action.sign > 0 else "bottom"
        return [Notice(f"resolution already at the {end} of the list")], state
    return [SetVideo(resolution=res)], state


def next_bitrate(kbps: int, direction: int) -> int:
    """The next step of :data:`BITRATE_STEPS_KBPS` above (``direction`` > 0) or below ``kbps``; ``kbps`` itself
    when none is left that way."""
    if direction > 0:
        return next((b for b in BITRATE_STEPS_KBPS if b > kbps), kbps)
    return next((b for b in reversed(BITRATE_STEPS_KBPS) if b < kbps), kbps)


def _bitrate_key(direction: int, state: TeleopState) -> list[Command]:
    """Y/H with H.264: the bitrate without feedback and the ceiling one step each way, together (the ceiling never
    below the start; a ceiling at the start stays at it: no raising with feedback)."""
    start, top = state.h264_bitrate_kbps, state.h264_max_bitrate_kbps
    if start is None or top is None:
        return [Notice("H.264 bitrate not known yet (no video/params)")]
    lo, hi = BITRATE_STEPS_KBPS[0], BITRATE_STEPS_KBPS[-1]
    new_start = max(lo, min(hi, next_bitrate(start, direction)))
    new_top = max(new_start, min(hi, next_bitrate(top, direction)))
    if (new_start, new_top) == (start, top):
        return [Notice(f"H.264 bitrate already at its limit ({start} kbit/s, up to {top} with feedback)")]
    return [SetVideo(h264_bitrate_kbps=new_start, h264_max_bitrate_kbps=new_top)]


_ARROWS = {"A": "<up>", "B": "<down>", "C": "<right>", "D": "<left>"}


def split_keys(data: str) -> list[str]:
    """Split what one read of a raw terminal returned into keys.

    Escape sequences (arrow keys, function keys: ``ESC [ … final`` or ``ESC O x``) become one token each —
    ``<left>`` etc. for arrows, ``<unknown>`` for the rest — so their bytes are never taken for letters
    (``ESC [ A`` must not pan by 5x). A lone ESC at the end of a read is the ESC key.
    """
    keys: list[str] = []
    i, n = 0, len(data)
    while i < n:
        c = data[i]
        if c == ESC and i + 1 < n and data[i + 1] in "[O":
            j = i + 2
            if data[i + 1] == "O":
                final = data[j] if j < n else ""
                keys.append(_ARROWS.get(final, "<unknown>"))
                i = j + 1
                continue
            while j < n and not ("\x40" <= data[j] <= "\x7e"):
                j += 1
            final = data[j] if j < n else ""
            params = data[i + 2 : j]
            keys.append(_ARROWS.get(final, "<unknown>") if params in ("", "1") else "<unknown>")
            i = j + 1
            continue
        keys.append(c)
        i += 1
    return keys


def key_label(key: str) -> str:
    """Printable name of a key for the help screen."""
    names = {" ": "SPACE", ESC: "ESC", CTRL_C: "Ctrl-C", CTRL_Q: "Ctrl-Q"}
    if key in names:
        return names[key]
    if key.startswith("<"):
        return key
    if len(key) == 1 and key.isalpha() and key.isupper():
        return f"SHIFT+{key}"
    return key.upper() if key.isalpha() else key


def help_lines() -> list[str]:
    """The help screen: one line per key (Table 5.3 order, then the additions)."""
    order = [
        "r", "f", "t", "g", "y", "h", *[str(d) for d in range(1, 10)],
        "a", "d", "w", "s", "q", "e", "A", "D", "W", "S", "Q", "E", " ",
        "<left>", "<right>", "<up>", "<down>", "x", ESC, "p", "?", CTRL_C, CTRL_Q,
    ]  # fmt: skip
    lines = []
    for k in order:
        a = KEYMAP[k]
        lines.append(f"  {key_label(k):>8}  {a.description}")
    return lines
