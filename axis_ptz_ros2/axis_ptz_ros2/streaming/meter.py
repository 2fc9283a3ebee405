"""Capped exponential back-off, the sliding-window frames/s + kbit/s meter and each consumer's reported count.
ROS-free."""

from __future__ import annotations

import threading
from collections import deque
from dataclasses import dataclass


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

    def next_after(self, elapsed_s: float) -> float:
        """:meth:`next`, less the ``elapsed_s`` the failed attempt already took (never negative): a connect that
        hung until its timeout has already waited (a camera dropping packets while it reboots), so the next try is
        not delayed twice."""
        return max(0.0, self.next() - elapsed_s)

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


class ConsumerCounts:
    """Each consumer's latest reported count (access units lost, pictures it could not show) and how much it grew
    since that consumer's previous report. Consumers come and go: past ``limit`` of them, all are forgotten at
    once (the next report of each is then its first)."""

    def __init__(self, limit: int = 64) -> None:
        self._last: dict[str, int] = {}
        self._limit = limit

    def grew(self, consumer: str, count: int, first: int | None = None) -> int:
        """Record ``count``; return how much it grew since the consumer's previous report (0 if it did not). A
        consumer's first report is compared with ``first`` (None: it has no growth); a count below the previous
        one (a restarted consumer) has none either."""
        before = self._last.get(consumer, first)
        if len(self._last) > self._limit and consumer not in self._last:
            self._last.clear()
        self._last[consumer] = count
        return count - before if before is not None and count > before else 0

    def forget(self, consumer: str | None = None) -> None:
        """Forget one consumer (None: all of them)."""
        if consumer is None:
            self._last.clear()
        else:
            self._last.pop(consumer, None)
