"""A full-quality still on demand (ROS-free): the camera's best JPEG, one at a time, fetched off the caller's thread.

The best JPEG is ``jpg/image.cgi`` at compression 0 and the camera's full resolution: the largest size of its own
list (``Properties.Image.Resolution``, as the stream's discovery learned it, else asked for here). The fetch runs on
a worker thread of its own (:meth:`StillTaker.start`), never on the caller's (the stream node's executor); a second
request while one is in flight is refused at once, never queued. ``on_done`` is called on the worker with a
:class:`Still` or the reason it failed; the taker is busy until ``on_done`` has returned (the node publishes the
still in it, so "in flight" lasts until the still is out).

Failures are worded for the operator (the camera's errors are already redacted by :mod:`axis_ptz_ros2.vapix`, and
the password is taken out again here): a camera that is not there fails within the client's connect timeout.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol

from axis_ptz_ros2.media.limits import BITRATE_RANGE_KBPS
from axis_ptz_ros2.streaming.jpeg import jpeg_sof
from axis_ptz_ros2.vapix.errors import AxisPtzError, redact
from axis_ptz_ros2.vapix.models import Resolution, VideoParams

#: the answer to a request while a still is in flight
BUSY = "a still is already being taken"
#: the JPEG compression of a still: the camera's best (VAPIX 0..100, 0 = least compressed)
STILL_COMPRESSION = 0


class StillCamera(Protocol):
    """What the taker needs of a camera client (:class:`~axis_ptz_ros2.vapix.VapixClient`)."""

    def snapshot(self, params: VideoParams) -> bytes:
        """One JPEG from ``jpg/image.cgi``."""
        ...

    def supported_resolutions(self) -> tuple[Resolution, ...]:
        """The camera's own resolution list."""
        ...

    def close(self) -> None:
        """Release its connection (a fetch in flight on another thread then fails)."""
        ...


@dataclass(frozen=True, slots=True)
class Still:
    """One still: the camera's JPEG as it sent it, the size asked for, when it arrived."""

    jpeg: bytes
    resolution: Resolution  # asked for, and what the JPEG's SOF header says (checked)
    arrival_ns: int  # wall clock (``time.time_ns``) when the last byte had arrived: the message's stamp
    fetch_s: float  # request to last byte (monotonic)
    components: int  # 3 = colour, 1 = greyscale (the JPEG's SOF)


@dataclass(frozen=True, slots=True)
class StillOutcome:
    """What a request came to: ``still`` or the ``error`` worded for the operator."""

    still: Still | None
    error: str = ""


def largest(resolutions: Sequence[Resolution]) -> Resolution:
    """The camera's full resolution: the most pixels (then the widest) of its list."""
    if not resolutions:
        raise ValueError("the camera lists no resolution")
    return max(resolutions, key=lambda r: (r.width * r.height, r.width))


def still_request(resolutions: Sequence[Resolution], camera: int = 1) -> VideoParams:
    """The ``image.cgi`` request of the best still: compression 0 at the largest of ``resolutions`` (``fps`` is
    not sent for a snapshot; 1 only satisfies :class:`VideoParams`)."""
    return VideoParams(largest(resolutions), 1, STILL_COMPRESSION, camera=camera)


class StillTaker:
    """One still at a time from ``camera`` (see the module docstring); thread-safe."""

    def __init__(
        self,
        connect: Callable[[], StillCamera],
        known_resolutions: Callable[[], Sequence[Resolution] | None],
        *,
        camera_index: int = 1,
        secrets: Sequence[str | None] = (),
        wall_ns: Callable[[], int] = time.time_ns,
    ) -> None:
        """``connect()``: a new client for each still (closed after it: no kept-alive connection to a camera that
        may have gone, so a camera that is not there fails within the connect timeout, never a read timeout);
        ``known_resolutions()``: the camera's list as learned elsewhere (None/empty: ask the camera);
        ``secrets``: taken out of every message (the password)."""
        self._connect = connect
        self._camera: StillCamera | None = None  # the client of the still in flight
        self._closed = False
        self._known = known_resolutions
        self._index = camera_index
        self._secrets = tuple(secrets)
        self._wall_ns = wall_ns
        self._busy = threading.Lock()
        self._thread: threading.Thread | None = None
        self.taken = 0  # stills delivered (for diagnostics and tests)
        self.failed = 0

    @property
    def busy(self) -> bool:
        """Whether a still is in flight."""
        return self._busy.locked()

    def start(self, on_done: Callable[[StillOutcome], None]) -> str | None:
        """Take a still on a worker thread and hand it to ``on_done`` there; returns at once. None if started,
        else the refusal (:data:`BUSY`)."""
        if not self._busy.acquire(blocking=False):
            return BUSY
        try:
            thread = threading.Thread(target=self._run, args=(on_done,), name="still", daemon=True)
            self._thread = thread
            thread.start()
        except BaseException:
            self._busy.release()
            raise
        return None

    def close(self, timeout: float) -> bool:
        """No still from here on: the one in flight is cut (its client closed) and joined (at most ``timeout`` s);
        True if none is left."""
        self._closed = True
        camera = self._camera
        if camera is not None:
            camera.close()
        thread = self._thread
        if thread is not None and thread.ident is not None:
            thread.join(timeout)
            return not thread.is_alive()
        return True

    def _run(self, on_done: Callable[[StillOutcome], None]) -> None:
        try:
            outcome = self.take()
            if outcome.still is None:
                self.failed += 1
            else:
                self.taken += 1
            on_done(outcome)
        finally:
            self._busy.release()

    def take(self) -> StillOutcome:
        """Fetch the still on this thread (what :meth:`start`'s worker runs); never raises for a camera failure."""
        if self._closed:
            return StillOutcome(None, "still failed: the node is shutting down")
        try:
            camera = self._camera = self._connect()
            try:
                listed = tuple(self._known() or ())
                if not listed:
                    listed = camera.supported_resolutions()
                params = still_request(listed, self._index)
                t0 = time.monotonic()
                jpeg = camera.snapshot(params)
                arrival = self._wall_ns()
                fetch_s = time.monotonic() - t0
            finally:
                self._camera = None
                camera.close()
        except (AxisPtzError, ValueError) as err:
            return StillOutcome(None, self._word(err))
        except Exception as err:  # noqa: BLE001 - any failure is an answer, never a dead worker
            return StillOutcome(None, self._word(err, unexpected=True))
        sof = jpeg_sof(jpeg)
        want = params.resolution
        if sof is None or (sof[0], sof[1]) != (want.width, want.height):
            got = "no SOF header" if sof is None else f"{sof[0]}x{sof[1]}"
            return StillOutcome(None, f"the camera sent {got} for a {want} still ({len(jpeg)} bytes)")
        return StillOutcome(Still(jpeg, want, arrival, fetch_s, sof[2]))

    def _word(self, err: BaseException, unexpected: bool = False) -> str:
        kind = f"{type(err).__name__}: " if unexpected else ""
        return redact(f"still failed: {kind}{err}", self._secrets)


def still_summary(still: Still) -> str:
    """The Trigger answer's message: size and resolution (and how long the camera took)."""
    return (
        f"still {still.resolution} px, compression {STILL_COMPRESSION}, {len(still.jpeg)} bytes, "
        f"fetched in {still.fetch_s * 1000:.0f} ms"
    )


class ExtraBytes:
    """Bytes sent on the link outside the live frames (stills), as a rate over a sliding window (thread-safe): the
    video controller adds it to the live stream's measured rate when it judges the budget."""

    def __init__(self, window_s: float) -> None:
        """``window_s`` > 0: how long a still's bytes count (the live meter's window)."""
        if window_s <= 0:
            raise ValueError("window must be positive")
        self.window_s = window_s
        self._samples: list[tuple[float, int]] = []
        self._lock = threading.Lock()

    def add(self, t: float, nbytes: int) -> None:
        """``nbytes`` went out at monotonic time ``t``."""
        with self._lock:
            self._samples.append((t, int(nbytes)))

    def kbps(self, now: float) -> float:
        """kbit/s of what went out in ``(now - window_s, now]``, spread over the whole window."""
        cutoff = now - self.window_s
        with self._lock:
            self._samples = [s for s in self._samples if s[0] > cutoff]
            total = sum(b for t, b in self._samples if t <= now)
        return total * 8.0 / 1000.0 / self.window_s


#: h264 mode: while a still crosses the link the live H.264 gets at most this fraction of the reference rate (the
#: link's budget, or ``h264_bitrate_kbps`` without feedback), so the still has the rest. H.264 at a small share of
#: its rate keeps its picture rate (the picture gets softer for a second or two); the MJPEG ladder would have to step
#: down in size or rate instead, so MJPEG keeps :data:`~.controller.STILL_SHARE` of its budget for one meter window.
#: Two-host bench, 2 Mbit/s + 2 %, six stills a run: paced at 1.6 Mbit/s (config/fastdds_weak_link.xml), 0.2 took
#: 1.9 s a still (the pace had to be 1.3 Mbit/s to leave the video its room), 0.12 1.55 s with the live video at
#: 23 fps, age p95 176 ms (0.3 before the pacing, when the GIL-holding wait starved the video). With the encoder
#: following its target again (after a re-open too, 859821a) 0.12 read 270-330 ms; paced at 1.5 Mbit/s, the home
#: view (245 kB) with 0.12: 1.61 s a still, live age p95 253 ms, 380-390 kbit/s of live video; with 0.06: 1.55-1.57 s,
#: 111 and 180 ms, 270-320 kbit/s (x264 does not go much lower at 704x576 and 25 fps); the acuity chart's (171 kB)
#: 1.10 s, 92 and 182 ms (ad hoc at 3b6c4b5)
STILL_H264_VIDEO_SHARE = 0.06
#: s: the longest a still is taken to be crossing when its end is reported (acknowledged by every reader)
STILL_CROSSING_MAX_S = 10.0


class StillWindow:
    """h264 mode: the time a still crosses the link, until the node says it has (thread-safe). Meanwhile the
    encoder's target is capped at :data:`STILL_H264_VIDEO_SHARE` of the reference rate, and consumers' reports
    covering that time are not judged: the queue the still makes is ours, not the link's congestion (without this,
    two stills of 170-245 kB on 2 Mbit/s + 2 % read as congestion and cut the budget to its 100 kbit/s floor: the
    live video fell from 25 to 5 fps and stills took 4.8 s or never came, two-host bench at dfd75bb)."""

    def __init__(self) -> None:
        self._until = -1e18
        self._cap_kbps = 0.0
        self._lock = threading.Lock()

    def start(self, now: float, reference_kbps: float) -> None:
        """A still goes out at ``now`` on a link of about ``reference_kbps`` (> 0): it is taken to be crossing until
        :meth:`end` says it has crossed (every reader acknowledged it), at most :data:`STILL_CROSSING_MAX_S`. Not an
        estimate from its size: on 2 Mbit/s + 2 % a 245 kB still took 1.8-5.0 s where 1.85 s was estimated, and the
        encoder back at its full rate under the rest of it read as congestion."""
        if reference_kbps <= 0:
            raise ValueError("reference_kbps must be positive")
        with self._lock:
            self._until = max(self._until, now + STILL_CROSSING_MAX_S)
            self._cap_kbps = STILL_H264_VIDEO_SHARE * reference_kbps

    def end(self, now: float) -> None:
        """The still has crossed (or will not): the cap ends now."""
        with self._lock:
            self._until = min(self._until, now)

    def cap(self, now: float, kbps: int) -> int:
        """The live H.264 target ``kbps`` while a still crosses (at most the cap, never under the parameters' lowest
        bitrate), else as it is."""
        with self._lock:
            if now >= self._until:
                return kbps
            return max(BITRATE_RANGE_KBPS[0], min(kbps, int(self._cap_kbps)))

    def covers(self, now: float, window_s: float) -> bool:
        """Whether a report of the last ``window_s`` seconds (received at ``now``) covers a still's crossing."""
        with self._lock:
            return now - window_s < self._until
