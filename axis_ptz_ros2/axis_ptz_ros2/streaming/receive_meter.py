"""The consumer's side of link adaptation (ROS-free): what arrives and how late, summarised as a
:class:`~axis_ptz_ros2.streaming.feedback.FeedbackReport` for ``video/feedback`` (the monitor and the web console,
``nodes/link_monitor.FeedbackPublisher``). The stream node's side, the adapter, is :mod:`.feedback`.
"""

from __future__ import annotations

import math
import threading
from collections import deque

from axis_ptz_ros2.streaming.feedback import FeedbackReport

#: s: the reference window of the smallest delay (clock offset + the link's fixed delay) a consumer reports; after a
#: step of either host's clock its reports mix the two clocks for this long (the stream node does not judge them)
BASE_WINDOW_S = 10.0


class ReceiveMeter:
    """The consumer's side: what arrives, and how late (thread-safe).

    ``add(rx_s, stamp_s, nbytes)`` per frame received (``rx_s`` and ``stamp_s`` on the wall clocks of the
    consumer and of the stream node: their offset cancels in the queueing delay the adapter uses);
    ``report(now_s)`` summarises the last ``window_s`` seconds, with the smallest delay of the last
    ``base_window_s`` seconds as the reference.
    """

    def __init__(self, consumer: str, window_s: float = 2.0, base_window_s: float = BASE_WINDOW_S) -> None:
        """``window_s`` > 0, ``base_window_s`` >= ``window_s``."""
        if window_s <= 0 or base_window_s < window_s:
            raise ValueError("need 0 < window_s <= base_window_s")
        self.consumer = consumer
        self.window_s = window_s
        self.base_window_s = base_window_s
        self._frames: deque[tuple[float, float, int]] = deque()  # (rx, delay, bytes)
        self._lock = threading.Lock()

    def add(self, rx_s: float, stamp_s: float, nbytes: int) -> None:
        """One frame stamped ``stamp_s`` by the sender arrived at ``rx_s``."""
        with self._lock:
            self._frames.append((rx_s, rx_s - stamp_s, nbytes))
            cutoff = rx_s - self.base_window_s
            while self._frames and self._frames[0][0] < cutoff:
                self._frames.popleft()

    def clock_stepped(self, step_s: float) -> None:
        """This host's wall clock (the arrivals' clock) stepped by ``step_s``: every arrival kept moves with it, and
        so its delay (the sender's stamps did not move), as if the new clock had always been in force: a step is no
        queue (before, a step of +0.5 s read as a 0.5 s queue for the whole base window)."""
        with self._lock:
            self._frames = deque((rx + step_s, delay + step_s, n) for rx, delay, n in self._frames)

    def report(self, now_s: float) -> FeedbackReport:
        """The last ``window_s`` seconds as a :class:`FeedbackReport`."""
        with self._lock:
            frames = list(self._frames)
        recent = [f for f in frames if f[0] > now_s - self.window_s]
        gap = now_s - frames[-1][0] if frames else math.inf
        base = [f[1] for f in frames if f[0] > now_s - self.base_window_s]
        if not recent:
            return FeedbackReport(self.consumer, 0, 0.0, 0.0, 0.0, min(base) if base else 0.0, gap, self.window_s)
        delays = sorted(f[1] for f in recent)
        p95 = delays[min(len(delays) - 1, int(math.ceil(0.95 * len(delays))) - 1)]
        p50 = delays[(len(delays) - 1) // 2]
        # the last half: the queue standing now, not one the report's earlier half saw drain
        floor = min((f[1] for f in recent if f[0] > now_s - self.window_s / 2), default=0.0)
        nbytes = sum(f[2] for f in recent)
        return FeedbackReport(
            consumer=self.consumer,
            frames=len(recent),
            fps=len(recent) / self.window_s,
            kbps=nbytes * 8.0 / 1000.0 / self.window_s,
            delay_p95_s=p95,
            delay_min_s=min(base),
            gap_s=gap,
            window_s=self.window_s,
            delay_p50_s=p50,
            delay_floor_s=floor,
        )
