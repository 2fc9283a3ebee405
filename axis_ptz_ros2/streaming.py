"""ROS-free machinery of the MJPEG stream node: reader thread, back-off, watchdog, meter, budget.

Implements the driver side of reference ``vapix.md`` §5.1 (one long ``mjpg/video.cgi`` request per
parameter set) and the MJPEG items of §12 (reconnect with back-off, never a stale frame):

* :class:`StreamReader` — the one justified thread. It opens the stream through an injected
  ``opener`` (normally :meth:`VapixClient.open_mjpeg`), hands every JPEG to ``on_frame`` *on the
  reader thread* with its arrival time, reconnects with :class:`Backoff` (capped exponential, reset
  after a good frame), retries a refused login slowly, and turns a stalled stream into a reconnect:
  a silent socket through the read timeout (the stall limit), bytes without frames through
  :meth:`StreamReader.check_watchdog` (called from the owner's timer). :meth:`StreamReader.stop`
  closes the stream from outside, so a blocked read ends at once.
* :class:`BitrateMeter` — frames/s and kbit/s over a short sliding window.
* :class:`BandwidthController` — a pure controller that keeps the measured bitrate under a budget by
  stepping compression (+10), then fps, then resolution down, and back up with hysteresis.
* :func:`jpeg_size`, :func:`jpeg_comments`, :func:`sim_stamp` — cheap JPEG header readers (the
  frame size from SOF without decoding; the simulator's ``axsim seq=<n> t=<ns>`` comment).

Nothing here imports ``rclpy`` or ROS messages.
"""

from __future__ import annotations

import math
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field, replace
from enum import StrEnum
from typing import Protocol

from axis_ptz_ros2.vapix.errors import AuthError, AxisPtzError, CameraTimeout, InvalidArgument
from axis_ptz_ros2.vapix.mjpeg import MjpegStats
from axis_ptz_ros2.vapix.models import Resolution, VideoParams

__all__ = [
    "AXIS214_PAL_RESOLUTIONS",
    "Backoff",
    "BandwidthController",
    "BitrateMeter",
    "BudgetConfig",
    "FrameSource",
    "ReaderConfig",
    "ReaderStats",
    "StreamOpener",
    "StreamReader",
    "StreamState",
    "compression_size_factor",
    "jpeg_comments",
    "jpeg_size",
    "sim_stamp",
]

#: Resolutions of the PAL Axis 214 PTZ (``vapix.md`` §5.5), used until the camera reports its own list.
AXIS214_PAL_RESOLUTIONS: tuple[Resolution, ...] = (
    Resolution(704, 576),
    Resolution(704, 288),
    Resolution(352, 288),
    Resolution(176, 144),
)


# ---------------------------------------------------------------------------------------------------------
# JPEG headers
# ---------------------------------------------------------------------------------------------------------
_SOF_MARKERS = frozenset({0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF})
_STANDALONE = frozenset({0x01, *range(0xD0, 0xD8)})


def _segments(data: bytes | bytearray | memoryview) -> Iterator[tuple[int, int, int]]:
    """``(marker, payload_start, payload_end)`` of the header segments up to SOS (no entropy data)."""
    n = len(data)
    if n < 4 or data[0] != 0xFF or data[1] != 0xD8:
        return
    i = 2
    while i + 4 <= n:
        if data[i] != 0xFF:
            return
        marker = data[i + 1]
        if marker == 0xFF:  # fill byte
            i += 1
            continue
        if marker in _STANDALONE:
            i += 2
            continue
        if marker in (0xD9, 0xDA):  # EOI / SOS: the header is over
            return
        length = (data[i + 2] << 8) | data[i + 3]
        if length < 2 or i + 2 + length > n:
            return
        yield marker, i + 4, i + 2 + length
        i += 2 + length


def jpeg_size(data: bytes | bytearray | memoryview) -> tuple[int, int] | None:
    """``(width, height)`` from the SOF segment, reading only the header; None if there is none."""
    for marker, start, end in _segments(data):
        if marker in _SOF_MARKERS and end - start >= 5:
            height = (data[start + 1] << 8) | data[start + 2]
            width = (data[start + 3] << 8) | data[start + 4]
            return (width, height) if width and height else None
    return None


def jpeg_comments(data: bytes | bytearray | memoryview) -> list[bytes]:
    """Payloads of the COM (``FF FE``) segments before the scan."""
    return [bytes(data[start:end]) for marker, start, end in _segments(data) if marker == 0xFE]


def sim_stamp(data: bytes | bytearray | memoryview) -> tuple[int, int] | None:
    """``(seq, t_ns)`` from the simulated camera's ``axsim seq=<n> t=<time_ns at send>`` comment."""
    for text in jpeg_comments(data):
        if not text.startswith(b"axsim"):
            continue
        fields = dict(tok.split(b"=", 1) for tok in text.split() if b"=" in tok)
        try:
            return int(fields[b"seq"]), int(fields[b"t"])
        except (KeyError, ValueError):
            return None
    return None


# ---------------------------------------------------------------------------------------------------------
# Back-off and meter
# ---------------------------------------------------------------------------------------------------------
class Backoff:
    """Capped exponential back-off: ``initial``, ×``factor`` per failure, at most ``maximum``."""

    def __init__(self, initial: float = 0.1, maximum: float = 2.0, factor: float = 2.0) -> None:
        """Delays in seconds; ``initial`` > 0, ``maximum`` >= ``initial``, ``factor`` >= 1."""
        if initial <= 0 or maximum < initial or factor < 1.0:
            raise ValueError(f"bad back-off {initial=}, {maximum=}, {factor=}")
        self.initial = initial
        self.maximum = maximum
        self.factor = factor
        self._next = initial

    def next(self) -> float:
        """The delay before the next attempt (and grow the one after)."""
        delay = self._next
        self._next = min(self._next * self.factor, self.maximum)
        return delay

    def reset(self) -> None:
        """After a success: start again from ``initial``."""
        self._next = self.initial

    @property
    def pending(self) -> float:
        """What :meth:`next` would return."""
        return self._next


@dataclass(frozen=True, slots=True)
class Rate:
    """What a :class:`BitrateMeter` measured over its window."""

    fps: float
    kbps: float
    bytes_per_frame: float
    span_s: float
    frames: int


class BitrateMeter:
    """Frames/s and kbit/s over the last ``window_s`` seconds (thread-safe; one short lock per call)."""

    def __init__(self, window_s: float = 2.0) -> None:
        """``window_s`` > 0."""
        if window_s <= 0:
            raise ValueError("window must be positive")
        self.window_s = window_s
        self._samples: deque[tuple[float, int]] = deque()
        self._lock = threading.Lock()

    def add(self, t: float, nbytes: int) -> None:
        """One frame of ``nbytes`` arrived at monotonic time ``t`` (seconds)."""
        with self._lock:
            self._samples.append((t, nbytes))
            cutoff = t - self.window_s
            while self._samples[0][0] <= cutoff:
                self._samples.popleft()

    def reset(self) -> None:
        """Forget everything (e.g. on a new connection with other parameters)."""
        with self._lock:
            self._samples.clear()

    def rate(self, now: float) -> Rate:
        """The rate of the frames that arrived in ``(now - window_s, now]``; zeros if fewer than two."""
        cutoff = now - self.window_s
        with self._lock:
            samples = [s for s in self._samples if s[0] > cutoff]
        if len(samples) < 2:
            return Rate(0.0, 0.0, float(samples[-1][1]) if samples else 0.0, 0.0, len(samples))
        span = samples[-1][0] - samples[0][0]
        if span <= 0:
            return Rate(0.0, 0.0, float(samples[-1][1]), 0.0, len(samples))
        counted = samples[1:]  # n-1 intervals, each closed by the frame that ends it
        total = sum(b for _, b in counted)
        return Rate(
            fps=len(counted) / span,
            kbps=total * 8.0 / 1000.0 / span,
            bytes_per_frame=total / len(counted),
            span_s=span,
            frames=len(samples),
        )


# ---------------------------------------------------------------------------------------------------------
# Reader thread
# ---------------------------------------------------------------------------------------------------------
class StreamState(StrEnum):
    """What the reader is doing (reported on /diagnostics)."""

    STOPPED = "stopped"
    IDLE_LAZY = "idle-lazy"
    CONNECTING = "connecting"
    STREAMING = "streaming"
    RECONNECTING = "reconnecting"
    AUTH_FAILED = "auth-failed"
    INVALID_PARAMS = "invalid-params"


class FrameSource(Protocol):
    """An open MJPEG stream (:class:`~axis_ptz_ros2.vapix.client.MjpegStream` is one)."""

    def __iter__(self) -> Iterator[bytes]:
        """Yield JPEG frames until closed or the stream ends."""
        ...

    def close(self) -> None:
        """Close from any thread; a blocked iteration ends promptly."""
        ...

    @property
    def stats(self) -> MjpegStats:
        """Parser counters."""
        ...


class StreamOpener(Protocol):
    """Open a stream with these parameters (raises :class:`AxisPtzError` subclasses)."""

    def __call__(self, params: VideoParams, read_timeout_s: float) -> FrameSource:
        """Connect and return the running stream."""
        ...


@dataclass(frozen=True, slots=True)
class ReaderConfig:
    """Timing of the reader (seconds)."""

    backoff_initial_s: float = 0.1
    backoff_max_s: float = 2.0
    auth_retry_s: float = 10.0
    stall_timeout_s: float = 1.0
    read_timeout_s: float = 5.0
    meter_window_s: float = 2.0

    def stall_limit(self, fps: int) -> float:
        """Frame age that counts as a stall at ``fps``: ``stall_timeout_s``, but at least 3 frame periods."""
        return max(self.stall_timeout_s, 3.0 / max(fps, 1))

    def read_timeout(self, fps: int) -> float:
        """Socket read timeout of a stream: a silent camera is a stall, detected inside the blocked read."""
        return min(self.read_timeout_s, self.stall_limit(fps))


@dataclass(frozen=True, slots=True)
class ReaderStats:
    """A snapshot of the reader's counters."""

    state: StreamState
    params: VideoParams
    frames: int
    connects: int
    reconnects: int
    stalls: int
    auth_failures: int
    last_error: str
    frame_age_s: float | None
    parser: MjpegStats = field(default_factory=MjpegStats)

    @property
    def drops(self) -> int:
        """Parts dropped by the parser (truncated or corrupt)."""
        return self.parser.dropped_truncated + self.parser.dropped_corrupt


def _add_stats(a: MjpegStats, b: MjpegStats) -> MjpegStats:
    return MjpegStats(
        frames=a.frames + b.frames,
        bytes=a.bytes + b.bytes,
        dropped_truncated=a.dropped_truncated + b.dropped_truncated,
        dropped_corrupt=a.dropped_corrupt + b.dropped_corrupt,
        garbage_bytes=a.garbage_bytes + b.garbage_bytes,
        resyncs=a.resyncs + b.resyncs,
    )


FrameCallback = Callable[[bytes, int], None]
"""``on_frame(jpeg, arrival_time_ns)``: called on the reader thread for every new frame."""
EventCallback = Callable[[StreamState, str], None]
"""``on_event(state, message)``: state changes and errors (message never contains credentials)."""


class StreamReader:
    """Owns the one reader thread: connect, read, publish through ``on_frame``, heal.

    ``set_params`` and ``set_active`` take effect at once (the current stream is closed from this
    thread of control and the reader reconnects without back-off). Unexpected ends (errors, end of
    stream, stalls) reconnect after :class:`Backoff`; a refused login retries after
    ``auth_retry_s``; parameters the camera cannot honour wait for new ones.
    """

    def __init__(
        self,
        opener: StreamOpener,
        on_frame: FrameCallback,
        params: VideoParams,
        config: ReaderConfig | None = None,
        *,
        on_event: EventCallback | None = None,
        active: bool = True,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        """Nothing runs until :meth:`start`."""
        self._opener = opener
        self._on_frame = on_frame
        self._on_event = on_event
        self._config = config or ReaderConfig()
        self._clock = clock
        self._params = params
        self._active = active
        self._backoff = Backoff(self._config.backoff_initial_s, self._config.backoff_max_s)
        self.meter = BitrateMeter(self._config.meter_window_s)
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._wake = threading.Event()
        self._thread: threading.Thread | None = None
        self._source: FrameSource | None = None
        self._restart = False  # the current stream was closed on purpose (new params, lazy, stop)
        self._stalled = False
        self._state = StreamState.STOPPED
        self._frames = 0
        self._connects = 0
        self._reconnects = 0
        self._stalls = 0
        self._auth_failures = 0
        self._last_error = ""
        self._last_frame: float | None = None
        self._connected_at: float | None = None
        self._parser_done = MjpegStats()

    # -- control (any thread) -----------------------------------------------------------------------------
    @property
    def config(self) -> ReaderConfig:
        """Timing configuration."""
        return self._config

    @property
    def params(self) -> VideoParams:
        """The parameters the reader streams with (or will, once active)."""
        return self._params

    @property
    def state(self) -> StreamState:
        """Current state."""
        return self._state

    def start(self) -> None:
        """Start the reader thread (once)."""
        if self._thread is not None:
            raise RuntimeError("reader already started")
        self._thread = threading.Thread(target=self._run, name="axis-mjpeg-reader", daemon=True)
        self._thread.start()

    def stop(self, timeout: float = 1.5) -> bool:
        """Stop and join; returns False if the thread did not end within ``timeout``."""
        self._stop.set()
        self._interrupt()
        thread = self._thread
        if thread is None:
            self._state = StreamState.STOPPED
            return True
        thread.join(timeout)
        return not thread.is_alive()

    def set_params(self, params: VideoParams) -> None:
        """Stream with ``params`` from now on (reconnects at once if they differ)."""
        with self._lock:
            if params == self._params:
                return
            self._params = params
        self._interrupt()

    def set_active(self, active: bool) -> None:
        """Lazy mode: inactive closes the stream and idles without any HTTP traffic."""
        with self._lock:
            if active == self._active:
                return
            self._active = active
        self._interrupt()

    def check_watchdog(self, now: float | None = None) -> bool:
        """Close a stream whose newest frame is older than the stall limit; True if it did."""
        now = self._clock() if now is None else now
        with self._lock:
            source = self._source
            if source is None or self._restart or self._stalled:
                return False
            last = self._last_frame if self._last_frame is not None else self._connected_at
            if last is None or now - last <= self._config.stall_limit(self._params.fps):
                return False
            self._stalled = True
        source.close()
        return True

    def stats(self) -> ReaderStats:
        """A consistent-enough snapshot for diagnostics."""
        with self._lock:
            source = self._source
            parser = self._parser_done
            last = self._last_frame
        if source is not None:
            parser = _add_stats(parser, source.stats)
        return ReaderStats(
            state=self._state,
            params=self._params,
            frames=self._frames,
            connects=self._connects,
            reconnects=self._reconnects,
            stalls=self._stalls,
            auth_failures=self._auth_failures,
            last_error=self._last_error,
            frame_age_s=None if last is None else self._clock() - last,
            parser=parser,
        )

    # -- internals -----------------------------------------------------------------------------------------
    def _interrupt(self) -> None:
        """Wake a back-off wait and close the current stream on purpose."""
        with self._lock:
            source = self._source
            if source is not None:
                self._restart = True
        self._wake.set()
        if source is not None:
            source.close()

    def _set_state(self, state: StreamState, message: str = "") -> None:
        changed = state != self._state
        self._state = state
        if message:
            self._last_error = message
        if self._on_event is not None and (changed or message):
            self._on_event(state, message)

    def _wait(self, seconds: float) -> None:
        """Sleep, but wake at once on stop/params/activity changes."""
        self._wake.wait(seconds)

    def _run(self) -> None:
        while not self._stop.is_set():
            self._wake.clear()
            with self._lock:
                active = self._active
                params = self._params
            if not active:
                self._set_state(StreamState.IDLE_LAZY)
                self._backoff.reset()
                self._wake.wait()
                continue
            if self._state not in (StreamState.RECONNECTING, StreamState.AUTH_FAILED):
                self._set_state(StreamState.CONNECTING)
            try:
                source = self._opener(params, self._config.read_timeout(params.fps))
            except AuthError as err:
                self._auth_failures += 1
                self._set_state(StreamState.AUTH_FAILED, str(err))
                self._wait(self._config.auth_retry_s)
                continue
            except InvalidArgument as err:
                self._set_state(StreamState.INVALID_PARAMS, str(err))
                self._wait(self._config.auth_retry_s)
                continue
            except AxisPtzError as err:
                self._reconnects += 1
                self._set_state(StreamState.RECONNECTING, str(err))
                self._wait(self._backoff.next())
                continue
            self._read(source, params)

        self._set_state(StreamState.STOPPED)

    def _read(self, source: FrameSource, params: VideoParams) -> None:
        with self._lock:
            if self._stop.is_set() or not self._active or params != self._params:
                discard = True
            else:
                discard = False
                self._source = source
                self._restart = False
                self._stalled = False
                self._connected_at = self._clock()
                self._last_frame = None
        if discard:
            source.close()
            return
        self._connects += 1
        self.meter.reset()
        error = ""
        first = True
        clock = self._clock
        on_frame = self._on_frame
        meter_add = self.meter.add
        try:
            for jpeg in source:
                arrival_ns = time.time_ns()
                now = clock()
                self._last_frame = now
                self._frames += 1
                meter_add(now, len(jpeg))
                if first:
                    first = False
                    self._backoff.reset()
                    self._set_state(StreamState.STREAMING)
                on_frame(jpeg, arrival_ns)
        except CameraTimeout as err:  # no byte for the stall limit: a stall seen from inside
            error = str(err)
            with self._lock:
                self._stalled = not self._restart
        except AxisPtzError as err:
            error = str(err)
        finally:
            source.close()
            with self._lock:
                self._source = None
                self._parser_done = _add_stats(self._parser_done, source.stats)
                deliberate = self._restart or self._stop.is_set()
                stalled = self._stalled
                self._restart = False
                self._stalled = False
        if deliberate:
            return
        self._reconnects += 1
        if stalled:
            self._stalls += 1
            limit = self._config.stall_limit(params.fps)
            error = f"stream stalled: no frame for {limit:.1f} s"
        self._set_state(StreamState.RECONNECTING, error or "camera ended the stream")
        self._wait(self._backoff.next())


# ---------------------------------------------------------------------------------------------------------
# Bandwidth budget
# ---------------------------------------------------------------------------------------------------------
# Relative JPEG size against compression, from the thesis's Table 6.2 (704x576 @ 30 fps: 3440, 2340 and
# 950 kbit/s at compression 0, 30 and 100). Only a prior: observed sizes replace it as soon as known.
_COMPRESSION_PRIOR: tuple[tuple[int, float], ...] = ((0, 1.0), (30, 0.68), (100, 0.276))


def compression_size_factor(compression: int) -> float:
    """Prior relative frame size at ``compression`` (1.0 at 0), piecewise linear through Table 6.2."""
    c = min(max(compression, 0), 100)
    for (c0, f0), (c1, f1) in zip(_COMPRESSION_PRIOR, _COMPRESSION_PRIOR[1:], strict=False):
        if c <= c1:
            return f0 + (f1 - f0) * (c - c0) / (c1 - c0)
    return _COMPRESSION_PRIOR[-1][1]


@dataclass(frozen=True, slots=True)
class BudgetConfig:
    """How the :class:`BandwidthController` steps (times in seconds, fractions of the budget)."""

    compression_step: int = 10
    max_compression: int = 60  # thesis §6: "values greater than 60 should not be used"
    fps_steps: tuple[int, ...] = (25, 20, 15, 10, 5, 2, 1)
    down_fraction: float = 0.9  # after stepping down, aim at a predicted rate below this
    up_fraction: float = 0.8  # step up only if the prediction stays below this ...
    up_hold_s: float = 3.0  # ... for this long
    settle_s: float = 0.8  # measure at least this long after a change before judging
    min_frames: int = 3
    scene_change: float = 0.3  # a frame-size jump of this fraction at fixed settings forgets what was learned
    memory_s: float = 30.0  # observations of other settings older than this are forgotten


class BandwidthController:
    """Keep the measured bitrate under ``budget_kbps`` by degrading the requested parameters in steps.

    The ladder starts at the requested parameters (level 0) and degrades one knob at a time:
    compression in steps of ``compression_step`` up to ``max_compression``, then fps through
    ``fps_steps``, then resolution through the smaller supported sizes. Over budget, it jumps straight
    to the first level predicted under ``down_fraction`` of the budget; with room, it climbs one level
    once the prediction for it has stayed under ``up_fraction`` for ``up_hold_s``. Predictions scale
    the observed bytes per frame (per resolution and compression, learned as it goes) by pixel count
    and the compression prior (raised to an exponent fitted to the camera's own sizes), times the fps the
    camera actually delivers. Climbing goes as far as the prediction leaves room.
    """

    def __init__(
        self,
        requested: VideoParams,
        budget_kbps: float = 0.0,
        resolutions: Sequence[Resolution] = AXIS214_PAL_RESOLUTIONS,
        config: BudgetConfig | None = None,
    ) -> None:
        """Start at level 0 (the request) with no observations."""
        self._config = config or BudgetConfig()
        self._requested = requested
        self._budget = float(budget_kbps)
        self._resolutions = tuple(resolutions)
        self._observed: dict[tuple[Resolution, int], float] = {}
        self._observed_at: dict[tuple[Resolution, int], float] = {}
        self._alpha = 1.0  # exponent on the compression prior, fitted to what this camera does
        self._ladder = self._build_ladder()
        self._level = 0
        self._changed_at: float | None = None
        self._up_since: float | None = None
        self._fps_cap: dict[Resolution, float] = {}

    # -- configuration -------------------------------------------------------------------------------------
    @property
    def budget_kbps(self) -> float:
        """0 = off."""
        return self._budget

    @property
    def level(self) -> int:
        """0 = the request; higher = more degraded."""
        return self._level

    @property
    def ladder(self) -> tuple[VideoParams, ...]:
        """Every parameter set the controller may choose, best first."""
        return self._ladder

    @property
    def current(self) -> VideoParams:
        """The parameters to stream with now."""
        return self._ladder[self._level]

    def configure(
        self,
        requested: VideoParams | None = None,
        budget_kbps: float | None = None,
        resolutions: Sequence[Resolution] | None = None,
        now: float | None = None,
    ) -> VideoParams:
        """Change the request, budget or resolution list; restarts from level 0 (re-judged by ``update``)."""
        if requested is not None:
            self._requested = requested
        if budget_kbps is not None:
            self._budget = float(budget_kbps)
        if resolutions is not None:
            self._resolutions = tuple(resolutions)
        self._ladder = self._build_ladder()
        self._level = 0
        self._changed_at = now
        self._up_since = None
        return self.current

    def _build_ladder(self) -> tuple[VideoParams, ...]:
        cfg = self._config
        p = self._requested
        ladder = [p]
        comp = p.compression
        while comp < cfg.max_compression:
            comp = min(comp + cfg.compression_step, cfg.max_compression)
            ladder.append(replace(p, compression=comp))
        last = ladder[-1]
        for fps in cfg.fps_steps:
            if fps < last.fps:
                last = replace(last, fps=fps)
                ladder.append(last)
        pixels = p.resolution.width * p.resolution.height
        smaller = sorted(
            (r for r in self._resolutions if r.width * r.height < pixels),
            key=lambda r: r.width * r.height,
            reverse=True,
        )
        for res in smaller:
            ladder.append(replace(last, resolution=res))
        return tuple(ladder)

    # -- prediction ----------------------------------------------------------------------------------------
    def _q(self, compression: int) -> float:
        """Relative frame size at ``compression``: the prior raised to the fitted exponent."""
        return float(compression_size_factor(compression) ** self._alpha)

    def _bytes_per_frame(self, p: VideoParams, ref: VideoParams, ref_bpf: float) -> float:
        known = self._observed.get((p.resolution, p.compression))
        if known is not None:
            return known
        # nearest observation at the same resolution, else the reference
        same_res = [(c, b) for (r, c), b in self._observed.items() if r == p.resolution]
        if same_res:
            c, b = min(same_res, key=lambda cb: abs(cb[0] - p.compression))
            return b * self._q(p.compression) / self._q(c)
        pixel_ratio = (p.resolution.width * p.resolution.height) / (ref.resolution.width * ref.resolution.height)
        return ref_bpf * pixel_ratio * self._q(p.compression) / self._q(ref.compression)

    def _fitted(self, resolution: Resolution) -> bool:
        """Whether two compressions at least one step apart were observed at ``resolution``."""
        comps = [c for (r, c) in self._observed if r == resolution]
        return len(comps) >= 2 and max(comps) - min(comps) >= self._config.compression_step

    def _fit_alpha(self) -> None:
        """Fit the compression exponent to the two most distant observations at one resolution."""
        best: tuple[int, float] | None = None
        by_res: dict[Resolution, list[tuple[int, float]]] = {}
        for (r, c), b in self._observed.items():
            by_res.setdefault(r, []).append((c, b))
        for points in by_res.values():
            if len(points) < 2:
                continue
            (c1, b1), (c2, b2) = min(points), max(points)
            p1, p2 = compression_size_factor(c1), compression_size_factor(c2)
            if c2 - c1 < 10 or b1 <= 0 or b2 <= 0 or p1 <= p2 * 1.01:
                continue
            alpha = math.log(b2 / b1) / math.log(p2 / p1)
            if best is None or c2 - c1 > best[0]:
                best = (c2 - c1, min(max(alpha, 0.2), 8.0))
        if best is not None:
            self._alpha = best[1]

    def predict_kbps(self, level: int, ref_bpf: float) -> float:
        """Predicted kbit/s at ``level``, from the current level's measured bytes per frame."""
        p = self._ladder[level]
        ref = self.current
        fps = float(p.fps)
        cap = self._fps_cap.get(p.resolution)
        if cap is not None:
            fps = min(fps, cap)
        return self._bytes_per_frame(p, ref, ref_bpf) * fps * 8.0 / 1000.0

    # -- control -------------------------------------------------------------------------------------------
    def update(self, now: float, kbps: float, fps: float, bytes_per_frame: float, frames: int) -> VideoParams | None:
        """Feed one measurement of the current level; return new parameters when the level changes."""
        cfg = self._config
        if self._budget <= 0:
            if self._level != 0:
                self._level = 0
                self._changed_at = now
                return self.current
            return None
        if self._changed_at is None:
            self._changed_at = now
        if now - self._changed_at < cfg.settle_s or frames < cfg.min_frames or bytes_per_frame <= 0:
            return None
        cur = self._learn(now, bytes_per_frame)
        if fps < 0.85 * cur.fps:  # the camera delivers less than asked at this size: remember its ceiling
            self._fps_cap[cur.resolution] = fps
        elif self._fps_cap.get(cur.resolution, 0.0) < fps:
            self._fps_cap.pop(cur.resolution, None)
        if kbps > self._budget:
            self._up_since = None
            target = cfg.down_fraction * self._budget
            level = self._level + 1
            if level >= len(self._ladder):
                return None  # already at the bottom
            nxt = self._ladder[level]
            probe = not self._fitted(cur.resolution) and (nxt.resolution, nxt.fps) == (cur.resolution, cur.fps)
            # With nothing learned about this camera's compression yet, take one compression step and
            # measure (cheap, and it calibrates the prior); otherwise jump to the first level predicted
            # under the target.
            while not probe and level < len(self._ladder) - 1 and self.predict_kbps(level, bytes_per_frame) > target:
                level += 1
            return self._go(level, now)
        if self._level == 0:
            self._up_since = None
            return None
        room = cfg.up_fraction * self._budget
        if self.predict_kbps(self._level - 1, bytes_per_frame) < room:
            if self._up_since is None:
                self._up_since = now
            if now - self._up_since >= cfg.up_hold_s:
                level = self._level - 1  # climb as far as the prediction leaves room
                while level > 0 and self.predict_kbps(level - 1, bytes_per_frame) < room:
                    level -= 1
                return self._go(level, now)
        else:
            self._up_since = None
        return None

    def _learn(self, now: float, bytes_per_frame: float) -> VideoParams:
        """Record the current level's frame size; forget others when the scene changed or they aged."""
        cfg = self._config
        cur = self.current
        key = (cur.resolution, cur.compression)
        previous = self._observed.get(key)
        if previous is not None and abs(bytes_per_frame - previous) > cfg.scene_change * previous:
            self._observed.clear()
            self._observed_at.clear()
            self._alpha = 1.0
        for k, t in list(self._observed_at.items()):
            if now - t > cfg.memory_s:
                del self._observed[k], self._observed_at[k]
        self._observed[key] = bytes_per_frame
        self._observed_at[key] = now
        self._fit_alpha()
        return cur

    def _go(self, level: int, now: float) -> VideoParams:
        self._level = level
        self._changed_at = now
        self._up_since = None
        return self.current
