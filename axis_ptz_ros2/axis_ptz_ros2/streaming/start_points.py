"""Start points for new H.264 viewers (issue 40). ROS-free.

With intra refresh the only IDRs are those asked for, and a viewer that sends no feedback (``rqt_image_view``, a
plain subscription) asks only by appearing. The stage sends it two (at once and 0.4 s later,
:meth:`~.h264.H264Stage.new_subscriber`); on a crowded link the keep-last-4 queue can replace both before they are
repaired, and the viewer then waits forever (issue 40: 331 access units in 20 s, none an IDR). So a new subscriber
is also sent an IDR at each of :data:`START_IDR_REPEATS_S` after it appeared, unless every H.264 subscriber has by
then reported on ``video/feedback`` that it shows pictures (frames, no decode errors: it has had a start point); a
consumer that does report asks for more itself through its decode errors (:meth:`StartPoints.report`).

The same bookkeeping says whether the encoder's intra-refresh wave may be longer than a second
(:meth:`StartPoints.long_wave`, :attr:`~axis_ptz_ros2.media.h264_settings.H264Settings.long_wave`): every H.264
viewer has reported on ``video/feedback`` about the H.264 stream for :data:`REPORTING_FOR_S` without a gap of
more than :data:`REPORT_GAP_S` (each loss of theirs then asks for an IDR: the wave need not heal anyone), and none
has reported access units it could not show for :data:`CLEAN_FOR_S`. The second condition is measured: each loss
costs an IDR squeezed into the link's small VBV buffer, and on a still scene x264 skips the blocks it blurred
until the refresh wave passes them, so a long wave kept each such blur for seconds (two-host bench, 1 Mbit/s +
2 %, a loss every ~4 s: PSNR median 35.8, 5th percentile 29.7 dB with a 4 s wave, 32.2 / 31.9 with 1 s). A new
viewer that does not report, a reporter that falls silent or leaves, or a reported loss ends the long wave at once
(the loss's own IDR is the re-open's), but a loss while the link is congested, or within :data:`CALM_S` of it,
does not: a new wave re-opens x264, whose rate control then starts cold, and re-opened in a congestion the
2 -> 1 Mbit/s step took 11.6-12.0 s to clear instead of 2.0-3.0 s (two-host bench, two runs each). A link that
keeps losing once the congestion has passed (random loss) ends it at its next loss.
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
#: s: a viewer counts as reporting once it has reported this long without a gap (the link monitor reports every
#: 0.5 s): a wave that changes re-opens the encoder (an IDR), so a viewer's first report does not yet change it
REPORTING_FOR_S: Final = 5.0
#: s: a gap between a viewer's reports longer than this and it no longer counts as reporting (six of the link
#: monitor's periods: a few reports lost on a weak link do not make the wave flap)
REPORT_GAP_S: Final = 3.0
#: s: no H.264 viewer has reported a loss for this long before the wave may be long again (a loss every ~4 s, as on
#: 1 Mbit/s + 2 %, keeps it at one second; a link that loses nothing lengthens it once)
CLEAN_FOR_S: Final = 30.0
#: s: losses this soon after the link adapter judged the link congested do not end the long wave (see the module
#: docstring)
CALM_S: Final = 4.0
#: consumers' streaks kept at most (past it, those not reporting now are forgotten, then all but the viewers')
MAX_REPORTERS: Final = 64


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
        self._reporting: dict[str, tuple[float, float]] = {}  # consumer: (first, last) H.264 report of its streak
        self._loss_at = -1e18  # the last H.264 report with access units its consumer could not show (monotonic)
        self._congested_at = -1e18  # the link adapter's last "congested" (monotonic)
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
            if subscribers <= 0:
                self._reporting.clear()  # nobody watches: every streak ends
        self.subscribers = subscribers

    def report(self, consumer: str, frames: int, errors: int) -> None:
        """A consumer's report about the H.264 stream: its count of access units it could not show (its report's
        window), when it grew (new losses), asks for a start point now (:meth:`H264Stage.consumer_errors`);
        pictures without errors mean it has had one."""
        now = self._clock()
        with self._lock:
            if frames > 0 and errors == 0:
                self._showing.add(consumer)
            else:
                self._showing.discard(consumer)
            if errors > 0 and now - self._congested_at >= CALM_S:
                self._loss_at = now
            first, last = self._reporting.get(consumer, (now, now))
            self._reporting[consumer] = (now if now - last > REPORT_GAP_S else first, now)
            if len(self._reporting) > MAX_REPORTERS:  # consumers that come and go: the viewers' streaks are kept
                kept = {k: v for k, v in self._reporting.items() if k in self._viewers or now - v[1] <= REPORT_GAP_S}
                if len(kept) > MAX_REPORTERS:
                    kept = {k: v for k, v in kept.items() if k in self._viewers}
                self._reporting = kept
        if self._stage.active:
            self._stage.consumer_errors(consumer, errors)

    def congested(self, now: float) -> None:
        """The link adapter judged the link congested now (a consumer's report): losses until :data:`CALM_S` later
        do not end the long wave."""
        with self._lock:
            self._congested_at = now

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

    def long_wave(self, now: float) -> bool:
        """Whether every H.264 viewer (at the last count) reports, and none lost anything lately (see the module
        docstring); False with none."""
        with self._lock:
            if not self._viewers or self.subscribers <= 0 or now - self._loss_at < CLEAN_FOR_S:
                return False
            for name in self._viewers:
                first, last = self._reporting.get(name, (now, -1e18))
                if now - last > REPORT_GAP_S or last - first < REPORTING_FOR_S:
                    return False
            return True

    @property
    def pending(self) -> bool:
        """Whether a start-point IDR is still due."""
        return bool(self._repeats)
