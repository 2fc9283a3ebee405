"""Start points for new H.264 viewers (issue 40). ROS-free.

With intra refresh the only IDRs are those asked for, and a viewer that sends no feedback (``rqt_image_view``, a
plain subscription) asks only by appearing. The stage sends it two (at once and 0.4 s later,
:meth:`~.h264.H264Stage.new_subscriber`); on a crowded link the keep-last-4 queue can replace both before they are
repaired, and the viewer then waits forever (issue 40: 331 access units in 20 s, none an IDR). So a new subscriber
is also sent an IDR at each of :data:`START_IDR_REPEATS_S` after it appeared, unless every H.264 subscriber has by
then reported on ``video/feedback`` that it shows pictures (frames, no decode errors: it has had a start point); a
consumer that does report asks for more itself through its decode errors (:meth:`StartPoints.report`).

"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable
from typing import Final

from axis_ptz_ros2.streaming.h264 import H264Stage

#: s after a new H.264 subscriber appeared: further IDRs for it (see the module docstring). The first within the
#: 2 s a viewer's first picture may take, the last ~5 s of congestion out; at least 1.2 s apart so that an intra
#: refresh wave (one per second of frames) still begins between them, and each costs one squeezed picture
START_IDR_REPEATS_S: Final = (1.2, 2.4, 4.8)


class StartPoints:
    """The H.264 viewers' start points (see the module docstring); thread-safe."""

    def __init__(self, stage: H264Stage, clock: Callable[[], float] = time.monotonic) -> None:
        """IDRs are asked of ``stage``."""
        self._stage = stage
        self._clock = clock
        self._lock = threading.Lock()
        self.subscribers = 0  # on the H.264 topics, at the last count
        self._repeats: deque[float] = deque()  # when the next start-point IDRs are due (monotonic)
        self._viewers: frozenset[str] = frozenset()  # the H.264 subscribers' nodes (fully qualified)
        self._showing: set[str] = set()  # consumers whose last H.264 report shows pictures without errors
        self.start_repeats = 0  # start-point IDRs asked for by the repeats

    def count(self, subscribers: int, viewers: Callable[[], frozenset[str]]) -> None:
        """The H.264 subscribers now; more than before: a new viewer, who needs a start point (an IDR now, another
        0.4 s later, and the repeats). ``viewers()``: their nodes, asked on every count while there are any (the
        node counts on matched events and at 1 Hz): across hosts the graph learns a subscription's node after the
        publisher has matched it (until then it lists none, or an unknown name), so names asked only when the
        count changed stayed wrong for good."""
        if subscribers == self.subscribers and subscribers <= 0:
            return
        names = viewers()
        if subscribers > self.subscribers:
            self._stage.new_subscriber()
            now = self._clock()
            with self._lock:
                self._repeats = deque(now + t for t in START_IDR_REPEATS_S)
        with self._lock:
            self._viewers = names
        self.subscribers = subscribers

    def report(self, consumer: str, frames: int, errors: int) -> None:
        """A consumer's report about the H.264 stream: its count of access units it could not show (its report's
        window), when it grew (new losses), asks for a start point now (:meth:`H264Stage.consumer_errors`);
        pictures without errors mean it has had one."""
        with self._lock:
            if frames > 0 and errors == 0:
                self._showing.add(consumer)
            else:
                self._showing.discard(consumer)
        if self._stage.active:
            self._stage.consumer_errors(consumer, errors)

    def repeat_due(self, now: float) -> bool:
        """Whether a start-point IDR is due now (counted in :attr:`start_repeats`; reader or RTSP thread)."""
        if not self._repeats or now < self._repeats[0]:
            return False
        with self._lock:
            while self._repeats and now >= self._repeats[0]:
                self._repeats.popleft()
            if self._viewers and self._viewers <= self._showing:
                self._repeats.clear()  # every viewer has reported pictures: it has had its start point
                return False
            self.start_repeats += 1
        return True

    @property
    def viewers(self) -> frozenset[str]:
        """The H.264 subscribers' nodes (fully qualified) at the last count."""
        with self._lock:
            return self._viewers

    @property
    def pending(self) -> bool:
        """Whether a start-point IDR is still due."""
        return bool(self._repeats)
