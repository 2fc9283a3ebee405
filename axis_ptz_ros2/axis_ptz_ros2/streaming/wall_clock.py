"""Steps of this host's wall clock (ROS-free, stdlib only).

Frames are stamped, and the link's delays measured, on the host's wall clock (:func:`time.time_ns`). That clock can
*step*: NTP or chrony setting it when the robot or the operator's laptop finds its time server (a robot booted in the
field, without network, may be off by hours), or someone setting it by hand. A slew (the usual NTP correction) moves
it against the monotonic clock by at most 0.5 ms a second; a step moves it at once. :class:`WallClockSteps` notices a
step as a change of ``wall − monotonic`` larger than :data:`STEP_THRESHOLD_S` between two looks, so that what holds
times on the wall clock can move them with it (the stream's RTP → host mapping, the consumers' delay windows) instead
of reading the step as a delay, a queue or a frozen clock.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Final

STEP_THRESHOLD_S: Final = 0.05  #: s: a larger change of ``wall − monotonic`` between two looks is a step


class WallClockSteps:
    """Thread-safe; ``wall_ns`` / ``mono_ns`` are the clocks (injectable for tests)."""

    def __init__(
        self,
        threshold_s: float = STEP_THRESHOLD_S,
        wall_ns: Callable[[], int] = time.time_ns,
        mono_ns: Callable[[], int] = time.monotonic_ns,
    ) -> None:
        if threshold_s <= 0:
            raise ValueError("threshold_s must be positive")
        self._threshold_ns = int(threshold_s * 1e9)
        self._wall_ns, self._mono_ns = wall_ns, mono_ns
        self._offset: int | None = None
        self._lock = threading.Lock()
        self.steps = 0  #: steps seen
        self.wall_at_look_ns = 0  #: the wall clock at the last look

    def check(self) -> int:
        """How far (ns) the wall clock stepped since the last look (0: no step; a slew is followed, not reported)."""
        with self._lock:
            return self._look()

    def check_read(self, read_ns: int) -> tuple[int, int]:
        """:meth:`check`, and ``read_ns`` (a wall-clock time read a moment before, in another thread perhaps) on the
        clock as it is now: moved by the step when it was read before it (:func:`in_old_basis`)."""
        with self._lock:
            step = self._look()
            if step and in_old_basis(read_ns, self.wall_at_look_ns, step):
                read_ns += step
            return step, read_ns

    def _look(self) -> int:
        wall = self._wall_ns()
        offset = wall - self._mono_ns()
        self.wall_at_look_ns = wall
        last, self._offset = self._offset, offset
        if last is None or abs(offset - last) <= self._threshold_ns:
            return 0
        self.steps += 1
        return offset - last


def in_old_basis(time_ns: int, now_ns: int, step_ns: int) -> bool:
    """Whether ``time_ns``, taken a little before ``now_ns`` (the look that found a step of ``step_ns``), was read
    before the step: its age is then nearer ``step_ns`` than 0 (a time read after the step is at most moments old)."""
    age = now_ns - time_ns
    return abs(age - step_ns) < abs(age)
