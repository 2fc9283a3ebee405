"""State polling logic (ROS-free): poll, estimate rates and motion, count failures, back off, resume.

The node calls :meth:`StatePoller.poll` from its state timer at ``state_rate``. A failed read is counted and
retried; after consecutive failures the poller backs off exponentially (capped), so an absent camera costs
almost nothing, and polls at the full rate again as soon as one read succeeds. Waiters (services with
``wait=true``) block on :meth:`StatePoller.wait_for` until a sample satisfies their predicate.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

from axis_ptz_ros2.ptz.backend import PtzBackendError, PtzReading

STILL_EPS_RAD = 2e-5  #: pan/tilt change between two polls below which the head counts as still
STILL_EPS_ZOOM = 0.5  #: zoom-unit change below which the zoom counts as still


@dataclass(frozen=True, slots=True)
class StateSample:
    """A reading with rates estimated from the previous one and whether the pose is changing."""

    reading: PtzReading
    pan_rate: float  # rad/s
    tilt_rate: float  # rad/s
    zoom_rate: float  # units/s
    head_moving: bool  # the pose changed since the previous successful poll
    seq: int  # increases by one per successful poll


@dataclass
class PollStats:
    """Counters of the poller (monotonic except ``consecutive_failures``)."""

    ok: int = 0
    failed: int = 0
    consecutive_failures: int = 0
    last_error: str = ""
    rate_hz: float = 0.0  # exponentially averaged rate of successful polls
    last_poll_s: float = 0.0  # duration of the last read


class StatePoller:
    """Turns backend reads into :class:`StateSample` s, with failure counting and capped back-off."""

    def __init__(
        self,
        read: Callable[[], PtzReading],
        period_s: float,
        max_backoff_s: float = 2.0,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        """``read`` is e.g. ``backend.read_state``; ``period_s`` is the nominal poll period."""
        self._read = read
        self.period_s = period_s
        self.max_backoff_s = max_backoff_s
        self._clock = clock
        self._next_attempt = -math.inf
        self._cond = threading.Condition()
        self._latest: StateSample | None = None
        self._last_ok_t: float | None = None
        self.stats = PollStats()

    @property
    def latest(self) -> StateSample | None:
        """The newest successful sample."""
        with self._cond:
            return self._latest

    def backoff_s(self) -> float:
        """Delay before the next attempt after the current run of failures."""
        n = self.stats.consecutive_failures
        if n == 0:
            return 0.0
        return float(min(self.max_backoff_s, self.period_s * 2.0 ** min(n, 30)))

    def poll(self) -> StateSample | None:
        """Read once if due (not backing off). Returns the new sample, or None (not due or failed)."""
        now = self._clock()
        if now < self._next_attempt:
            return None
        t0 = self._clock()
        try:
            reading = self._read()
        except PtzBackendError as err:
            t1 = self._clock()
            with self._cond:
                self.stats.failed += 1
                self.stats.consecutive_failures += 1
                self.stats.last_error = str(err)
                self.stats.last_poll_s = t1 - t0
                self._next_attempt = t1 + self.backoff_s()
            return None
        t1 = self._clock()
        with self._cond:
            prev = self._latest
            if prev is not None and reading.stamp_ns > prev.reading.stamp_ns:
                dt = (reading.stamp_ns - prev.reading.stamp_ns) / 1e9
                dp = reading.pan - prev.reading.pan
                dtl = reading.tilt - prev.reading.tilt
                dz = reading.zoom - prev.reading.zoom
                rates = (dp / dt, dtl / dt, dz / dt)
                moving = abs(dp) > STILL_EPS_RAD or abs(dtl) > STILL_EPS_RAD or abs(dz) > STILL_EPS_ZOOM
            else:
                rates, moving = (0.0, 0.0, 0.0), False
            sample = StateSample(reading, *rates, moving, (prev.seq + 1) if prev is not None else 1)
            self._latest = sample
            if self._last_ok_t is not None and t1 > self._last_ok_t:
                inst = 1.0 / (t1 - self._last_ok_t)
                self.stats.rate_hz = inst if self.stats.rate_hz == 0.0 else 0.9 * self.stats.rate_hz + 0.1 * inst
            self._last_ok_t = t1
            self.stats.ok += 1
            self.stats.consecutive_failures = 0
            self.stats.last_poll_s = t1 - t0
            self._next_attempt = -math.inf
            self._cond.notify_all()
        return sample

    def wait_for(
        self, predicate: Callable[[StateSample], bool], timeout: float, after_seq: int = 0
    ) -> StateSample | None:
        """Block until a sample newer than ``after_seq`` satisfies ``predicate``; None on timeout."""
        deadline = self._clock() + timeout
        with self._cond:
            while True:
                s = self._latest
                if s is not None and s.seq > after_seq and predicate(s):
                    return s
                left = deadline - self._clock()
                if left <= 0.0:
                    return None
                self._cond.wait(min(left, 0.1))
