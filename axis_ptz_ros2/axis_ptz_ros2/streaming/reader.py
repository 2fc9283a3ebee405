"""The MJPEG reader thread (reference ``vapix.md`` §5.1 and §12): one long ``mjpg/video.cgi`` request per
parameter set, every JPEG handed to ``on_frame`` on the reader thread with its arrival time, reconnect
with :class:`~axis_ptz_ros2.streaming.meter.Backoff`, a refused login retried slowly, a stalled stream
turned into a reconnect (silent socket through the read timeout; bytes without frames through
:meth:`StreamReader.check_watchdog`). :meth:`StreamReader.stop` closes the stream from outside. ROS-free.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Protocol

from axis_ptz_ros2.streaming.meter import Backoff, BitrateMeter
from axis_ptz_ros2.streaming.worker import Worker
from axis_ptz_ros2.vapix.errors import AuthError, AxisPtzError, CameraTimeout, InvalidArgument
from axis_ptz_ros2.vapix.mjpeg import MjpegStats
from axis_ptz_ros2.vapix.models import VideoParams


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
    """Timing of a stream reader (seconds): this MJPEG reader's, and the RTSP pass-through's
    (:class:`~axis_ptz_ros2.streaming.rtsp_source.RtspH264Source`, which has no meter)."""

    backoff_initial_s: float = 0.1
    backoff_max_s: float = 1.0
    auth_retry_s: float = 10.0
    auth_grace_s: float = 120.0  #: a 401 this soon after frames flowed is a rebooting camera: retry on back-off
    stall_timeout_s: float = 1.0  #: no frame for this long (at least 3 frame periods): the stream is dead
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

    ``set_params`` (or ``refresh``) and ``set_active`` take effect at once (the current stream is closed from this
    thread of control and the reader reconnects without back-off). Unexpected ends (errors, end of
    stream, stalls) reconnect after :class:`Backoff`; a refused login retries after
    ``auth_retry_s``; parameters the camera cannot honour wait for new ones.
    """

    def __init__(
        self,
        opener: StreamOpener,
        on_frame: FrameCallback,
        params: VideoParams | Callable[[], VideoParams],
        config: ReaderConfig | None = None,
        *,
        on_event: EventCallback | None = None,
        active: bool = True,
        clock: Callable[[], float] = time.monotonic,
        meter: BitrateMeter | None = None,
    ) -> None:
        """Nothing runs until :meth:`start`. ``params``: fixed parameters (changed with :meth:`set_params`), or
        where to read them (their one owner; call :meth:`refresh` after they change). ``meter``: the meter to
        feed (a new one of ``meter_window_s`` if None)."""
        self._opener = opener
        self._on_frame = on_frame
        self._on_event = on_event
        self._config = config or ReaderConfig()
        self._clock = clock
        self._owned = isinstance(params, VideoParams)  # fixed parameters, changed with set_params
        if isinstance(params, VideoParams):
            self._fixed = params
            self._params_of: Callable[[], VideoParams] = lambda: self._fixed
        else:
            self._fixed = params()
            self._params_of = params
        self._attempt: VideoParams | None = None  # what the latest connection asked for
        cfg = self._config
        self._backoff = Backoff(cfg.backoff_initial_s, max(cfg.backoff_max_s, cfg.backoff_initial_s))
        self.meter = meter if meter is not None else BitrateMeter(cfg.meter_window_s)
        self._lock = threading.Lock()
        self._worker = Worker("reader", "axis-mjpeg-reader", self._run, self._interrupt, active=active)
        self._stop = self._worker.stopping
        self._wake = threading.Event()
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
        return self._params_of()

    @property
    def state(self) -> StreamState:
        """Current state."""
        return self._state

    def start(self) -> None:
        """Start the reader thread (once)."""
        self._worker.start()

    def stop(self, timeout: float = 1.5) -> bool:
        """Stop and join; returns False if the thread did not end within ``timeout``."""
        ended = self._worker.stop(timeout)
        if not self._worker.started:
            self._state = StreamState.STOPPED
        return ended

    def set_params(self, params: VideoParams) -> None:
        """Stream with ``params`` from now on (reconnects at once if they differ); fixed parameters only."""
        if not self._owned:
            raise TypeError("this reader reads its parameters from their owner: call refresh()")
        with self._lock:
            if params == self._fixed:
                return
            self._fixed = params
        self._interrupt()

    def refresh(self) -> None:
        """The owner's parameters changed: reconnect at once if they differ from the latest connection's."""
        with self._lock:
            if self._params_of() == self._attempt:
                return
        self._interrupt()

    def set_active(self, active: bool) -> None:
        """Lazy mode: inactive closes the stream and idles without any HTTP traffic."""
        self._worker.set_active(active)

    def check_watchdog(self, now: float | None = None) -> bool:
        """Close a stream whose newest frame is older than the stall limit; True if it did."""
        now = self._clock() if now is None else now
        with self._lock:
            source = self._source
            if source is None or self._restart or self._stalled:
                return False
            last = self._last_frame if self._last_frame is not None else self._connected_at
            if last is None or now - last <= self._config.stall_limit(self._params_of().fps):
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
            params=self._params_of(),
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

    def _retry_delay(self, attempt_start: float) -> float:
        """Back-off counted from the start of the failed attempt (:meth:`Backoff.next_after`)."""
        return self._backoff.next_after(self._clock() - attempt_start)

    def _run(self) -> None:
        while not self._stop.is_set():
            self._wake.clear()
            with self._lock:
                active = self._worker.active
                params = self._params_of()
                self._attempt = params
            if not active:
                self._set_state(StreamState.IDLE_LAZY)
                self._backoff.reset()
                self._wake.wait()
                continue
            if self._state not in (StreamState.RECONNECTING, StreamState.AUTH_FAILED):
                self._set_state(StreamState.CONNECTING)
            attempt = self._clock()
            try:
                source = self._opener(params, self._config.read_timeout(params.fps))
            except AuthError as err:
                self._auth_failures += 1
                last = self._last_frame
                if last is not None and self._clock() - last < self._config.auth_grace_s:
                    # Frames flowed with these credentials moments ago: a camera that is still booting
                    # answers 401 before its user database is up. Keep the normal back-off.
                    self._reconnects += 1
                    self._set_state(StreamState.RECONNECTING, f"{err} (camera restarting?)")
                    self._wait(self._retry_delay(attempt))
                    continue
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
                self._wait(self._retry_delay(attempt))
                continue
            self._read(source, params)

        self._set_state(StreamState.STOPPED)

    def _read(self, source: FrameSource, params: VideoParams) -> None:
        with self._lock:
            if self._stop.is_set() or not self._worker.active or params != self._params_of():
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
