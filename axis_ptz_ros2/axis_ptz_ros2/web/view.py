"""What the console page shows, kept ROS-free: PTZ state, video parameters, the measured stream, errors, keys.

:class:`ConsoleModel` holds everything the ``axis_web_console`` node learns (from topics, from commands)
behind one lock; the node feeds it and asks it for :meth:`ConsoleModel.state`, the JSON of ``GET /api/state``.
The PTZ video is metered with the package's one meter (:class:`axis_ptz_ros2.streaming.meter.BitrateMeter`).
Messages are read through small protocols (attribute names of ``PtzState`` / ``VideoParams``), so tests
use plain objects. The answers to the operator's commands are worded here too (:func:`service_answer` & co.); the
video parameters in words are the keyboard teleop's (:func:`axis_ptz_ros2.teleop.status.video_text`).
"""

from __future__ import annotations

import math
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any, Protocol

from axis_ptz_ros2.streaming.meter import BitrateMeter
from axis_ptz_ros2.teleop import keymap
from axis_ptz_ros2.teleop.status import video_text as video_text  # re-exported: the keyboard teleop's words
from axis_ptz_ros2.web.api import BadRequest, video_limits
from axis_ptz_ros2.web.backend import CommandResult

#: Browser ``KeyboardEvent.key`` for the key map's special keys (letters and digits are themselves).
BROWSER_KEYS = {"<left>": "ArrowLeft", "<right>": "ArrowRight", "<up>": "ArrowUp", "<down>": "ArrowDown",
                keymap.ESC: "Escape", " ": " "}  # fmt: skip
FROM_BROWSER = {v: k for k, v in BROWSER_KEYS.items()}
MAX_ERRORS = 8
LATENCY_SAMPLES = 30


class PtzStateLike(Protocol):
    """The fields of ``axis_ptz_interfaces/PtzState`` the page shows."""

    pan: float
    tilt: float
    zoom: float
    magnification: float
    hfov: float
    vfov: float
    moving: bool
    zoom_min: float
    zoom_max: float
    zoom_capped: bool
    zoom_cap: float
    requested_zoom: float


class VideoParamsLike(Protocol):
    """The fields of ``axis_ptz_interfaces/VideoParams`` the page shows."""

    fps: int
    resolution: str
    width: int
    height: int
    compression: int
    max_bitrate_kbps: int
    source: str
    available_resolutions: Sequence[str]
    codec: str
    h264_bitrate_kbps: int
    h264_max_bitrate_kbps: int


def finite(obj: Any) -> Any:  # noqa: ANN401 - JSON values
    """JSON has no NaN/inf: replace them by None (recursively)."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: finite(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [finite(v) for v in obj]
    return obj


def keymap_json() -> dict[str, Any]:
    """The keyboard teleop's key map for the page (quit keys left out)."""
    keys = [
        {"key": k, "browser": BROWSER_KEYS.get(k, k), "label": keymap.key_label(k), "kind": str(a.kind),
         "description": a.description}
        for k, a in keymap.KEYMAP.items()
        if a.kind is not keymap.Kind.QUIT
    ]  # fmt: skip
    return {"keys": keys}


def move_text(c: keymap.RelativeMove) -> str:
    """``pan +10° tilt -5°``: what a relative teleop move does."""
    parts = []
    if not math.isnan(c.pan):
        parts.append(f"pan {math.degrees(c.pan):+.0f}°")
    if not math.isnan(c.tilt):
        parts.append(f"tilt {math.degrees(c.tilt):+.0f}°")
    if not math.isnan(c.zoom):
        parts.append(f"zoom {c.zoom:+.0f}")
    return " ".join(parts)


def _note(message: str) -> str:
    return f" ({message})" if message else ""


def service_answer(success: bool, message: str, what: str) -> CommandResult:
    """A node's answer to a command: success is ``what`` (+ the node's note), a refusal the node's reason (409)."""
    if success:
        return CommandResult(True, what + _note(message))
    return CommandResult(False, f"{what}: refused: {message or 'no reason given'}", 409)


def video_answer(success: bool, message: str, in_effect: str) -> CommandResult:
    """The stream node's answer to ``video/set_params``; ``in_effect``: the parameters it now streams with."""
    if not success:
        return CommandResult(False, message or "video parameters refused", 409)
    return CommandResult(True, f"video {in_effect}" + _note(message))


def budget_answer(successful: bool, reason: str, kbps: int) -> CommandResult:
    """The stream node's answer to a ``max_bitrate_kbps`` set (0 = off)."""
    if not successful:
        return CommandResult(False, f"bandwidth budget refused: {reason or 'no reason given'}", 409)
    return CommandResult(True, f"bandwidth budget {kbps} kbit/s" if kbps else "bandwidth budget off")


def in_turn(steps: Iterable[Callable[[], CommandResult]]) -> CommandResult:
    """Run the steps of one command in turn: the first refusal ends it (later steps are not run); else one
    success with their messages joined by ``; ``."""
    messages = []
    for step in steps:
        result = step()
        if not result.ok:
            return result
        messages.append(result.message)
    return CommandResult(True, "; ".join(messages))


def ptz_json(s: PtzStateLike, age_s: float) -> dict[str, Any]:
    """The page's view of a PTZ state (angles also in degrees; a NaN zoom cap = off, shown as null)."""
    return {
        "pan_rad": s.pan, "tilt_rad": s.tilt, "pan_deg": math.degrees(s.pan), "tilt_deg": math.degrees(s.tilt),
        "zoom": s.zoom, "magnification": s.magnification, "hfov_deg": math.degrees(s.hfov),
        "vfov_deg": math.degrees(s.vfov), "moving": bool(s.moving), "age_s": age_s,
        "zoom_min": s.zoom_min, "zoom_max": s.zoom_max,
        "zoom_capped": bool(s.zoom_capped), "zoom_cap": s.zoom_cap, "requested_zoom": s.requested_zoom,
    }  # fmt: skip


def video_json(v: VideoParamsLike) -> dict[str, Any]:
    """The page's view of the stream node's video parameters."""
    return {
        "fps": v.fps, "resolution": v.resolution, "width": v.width, "height": v.height,
        "compression": v.compression, "max_bitrate_kbps": v.max_bitrate_kbps, "source": v.source,
        "codec": v.codec or "mjpeg", "h264_bitrate_kbps": v.h264_bitrate_kbps,
        "h264_max_bitrate_kbps": v.h264_max_bitrate_kbps, "text": video_text(v),
    }  # fmt: skip


class ConsoleModel:
    """Everything the page shows, fed by the node from any thread (one lock)."""

    def __init__(self, clock: Callable[[], float] = time.monotonic, wall: Callable[[], float] = time.time) -> None:
        """``clock``: monotonic seconds (ages, meter); ``wall``: epoch seconds (latency, error times)."""
        self._clock = clock
        self._wall = wall
        self._lock = threading.Lock()
        self._errors: deque[dict[str, Any]] = deque(maxlen=MAX_ERRORS)
        self._ptz: PtzStateLike | None = None
        self._ptz_t = 0.0
        self._video: VideoParamsLike | None = None
        self._diag: dict[str, str] = {}
        self._diag_t = 0.0
        self._last_click: dict[str, Any] | None = None
        self._latency: deque[float] = deque(maxlen=LATENCY_SAMPLES)
        self._teleop = keymap.TeleopState()
        self.meter = BitrateMeter()
        self._decoder: dict[str, Any] = {"mode": "", "decoded": 0, "errors": 0, "codec": "", "note": "", "reports": 0}

    # -- inputs --------------------------------------------------------------------------------------
    def ptz_frame(self, nbytes: int, stamp_s: float) -> None:
        """One PTZ frame of ``nbytes`` arrived now; ``stamp_s`` is its capture stamp (epoch s, 0 = none)."""
        self.meter.add(self._clock(), nbytes)
        if stamp_s > 0:
            with self._lock:
                self._latency.append(self._wall() - stamp_s)

    def ptz_state(self, msg: PtzStateLike) -> None:
        """The newest ``ptz/state``."""
        with self._lock:
            self._ptz, self._ptz_t = msg, self._clock()

    def video_params(self, msg: VideoParamsLike) -> None:
        """The stream node's ``video/params``: shown, and the teleop's next video steps start from it."""
        with self._lock:
            self._video = msg
            # the camera's own resolution list, from the stream node; the quality keys act on the JPEG compression
            # or, in H.264 mode, on the bitrates (as the keyboard teleop's)
            self._teleop = keymap.with_video(self._teleop, msg)

    def diagnostics(self, name: str, message: str, values: Mapping[str, str]) -> None:
        """One ``/diagnostics`` status: the stream node's (fps and kbit/s) is shown as the driver's view."""
        if any(k in values for k in ("fps", "kbit/s")) and ("stream" in name.lower() or "video" in name.lower()):
            with self._lock:
                self._diag = {"name": name, "message": message, **values}
                self._diag_t = self._clock()

    def error(self, message: str) -> None:
        """A refused or failed command, for the page's error list."""
        with self._lock:
            self._errors.append({"time": self._wall(), "message": message})

    def decoder(self, mode: str, decoded: int, errors: int, codec: str, note: str) -> None:
        """A page's decoder report: ``decoded`` / ``errors`` are its counts since its previous report (summed here
        over every page), the rest is the newest page's mode, codec and fallback reason."""
        with self._lock:
            d = self._decoder
            d["decoded"] += decoded
            d["errors"] += errors
            d["reports"] += 1
            d.update(mode=mode, codec=codec, note=note, age_t=self._clock())

    def click(self, info: dict[str, Any]) -> None:
        """The last panorama click and where it pointed."""
        with self._lock:
            self._last_click = dict(info)

    def key(self, raw: str) -> tuple[str, list[keymap.Command], int]:
        """A browser key → (its label, the teleop commands, the step size after it); BadRequest if unmapped."""
        key = FROM_BROWSER.get(raw, raw)
        action = keymap.KEYMAP.get(key)
        if action is None or action.kind is keymap.Kind.QUIT:
            raise BadRequest(f"key {raw[:32]!r} is not in the key map")
        with self._lock:
            commands, self._teleop = keymap.apply(key, self._teleop)
            step = self._teleop.step
        return keymap.key_label(key), commands, step

    # -- output --------------------------------------------------------------------------------------
    def state(self, stream_watched: bool, extra: Mapping[str, Any]) -> dict[str, Any]:
        """``GET /api/state``: the model's view plus the node's ``extra`` fields (services, watchers, …)."""
        now = self._clock()
        with self._lock:
            s, s_t, v = self._ptz, self._ptz_t, self._video
            diag, diag_t = dict(self._diag), self._diag_t
            lat = sorted(self._latency)
            errors = list(self._errors)
            click = dict(self._last_click) if self._last_click else None
            resolutions = list(self._teleop.resolutions)
            step = self._teleop.step
            dec = dict(self._decoder)
        dec["age_s"] = now - dec.pop("age_t") if "age_t" in dec else None
        video = video_json(v) if v is not None else None
        rate = self.meter.rate(now)
        stream = {
            "measured_at": "console" if stream_watched else "none",
            "fps": rate.fps,
            "kbps": rate.kbps,
            "latency_ms": lat[len(lat) // 2] * 1000.0 if lat and stream_watched else None,
        }
        out: dict[str, Any] = {
            "ptz": ptz_json(s, now - s_t) if s is not None else None,
            "video": video,
            "resolutions": resolutions,
            "budget_kbps": video["max_bitrate_kbps"] if video else None,
            "stream": stream,
            "driver": {**diag, "age_s": now - diag_t} if diag else None,
            "last_click": click,
            "step": step,
            "errors": errors,
            "decoder": dec,
            "limits": video_limits(),  # the quality form's ranges: the page keeps no copy
            "time": self._wall(),
        }
        for k, val in extra.items():
            if isinstance(out.get(k), dict) and isinstance(val, dict):
                out[k] = {**out[k], **val}
            else:
                out[k] = val
        result: dict[str, Any] = finite(out)
        return result
