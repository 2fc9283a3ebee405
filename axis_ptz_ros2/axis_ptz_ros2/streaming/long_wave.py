"""Whether the encoder's intra-refresh wave may be longer than a second (``h264_reported_wave``, opt-in). ROS-free.

:meth:`LongWave.allowed` says so while every H.264 viewer (the subscribers' nodes at the last count,
:meth:`LongWave.set_viewers`) has reported on ``video/feedback`` about the H.264 stream for :data:`REPORTING_FOR_S`
without a gap of more than :data:`REPORT_GAP_S` (each loss of theirs then asks for an IDR: the wave need not heal
anyone), and none has reported access units it could not show for :data:`CLEAN_FOR_S`. The stream node then sets
:attr:`~axis_ptz_ros2.media.h264_settings.H264Settings.long_wave`.

The second condition is measured: each loss costs an IDR squeezed into the link's small VBV buffer, and on a still
scene x264 skips the blocks it blurred until the refresh wave passes them, so a long wave kept each such blur for
seconds (two-host bench, 1 Mbit/s + 2 %, a loss every ~4 s: PSNR median 35.8, 5th percentile 29.7 dB with a 4 s
wave, 32.2 / 31.9 with 1 s). A new viewer that does not report, a reporter that falls silent or leaves, or a
reported loss ends the long wave at once (the loss's own IDR is the re-open's), but a loss while the link is
congested, or within :data:`CALM_S` of it, does not: a new wave re-opens x264, whose rate control then starts cold,
and re-opened in a congestion the 2 -> 1 Mbit/s step took 11.6-12.0 s to clear instead of 2.0-3.0 s (two-host
bench, two runs each). A link that keeps losing once the congestion has passed (random loss) ends it at its next
loss. Why it is opt-in: docs/weak-link.md, "A longer wave while every viewer reports".
"""

from __future__ import annotations

import threading
from typing import Final

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


class LongWave:
    """Who reports and what they lost (see the module docstring); thread-safe. Times are monotonic seconds."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._viewers: frozenset[str] = frozenset()  # the H.264 subscribers' nodes (fully qualified)
        self._reporting: dict[str, tuple[float, float]] = {}  # consumer: (first, last) H.264 report of its streak
        self._loss_at = -1e18  # the last H.264 report with access units its consumer could not show
        self._congested_at = -1e18  # the link adapter's last "congested"

    def set_viewers(self, viewers: frozenset[str]) -> None:
        """The H.264 subscribers' nodes now (none: every streak ends)."""
        with self._lock:
            self._viewers = viewers
            if not viewers:
                self._reporting.clear()

    def report(self, consumer: str, errors: int, now: float) -> None:
        """A consumer's report about the H.264 stream at ``now``, with ``errors`` access units it could not show."""
        with self._lock:
            if errors > 0 and now - self._congested_at >= CALM_S:
                self._loss_at = now
            first, last = self._reporting.get(consumer, (now, now))
            self._reporting[consumer] = (now if now - last > REPORT_GAP_S else first, now)
            if len(self._reporting) > MAX_REPORTERS:  # consumers that come and go: the viewers' streaks are kept
                kept = {k: v for k, v in self._reporting.items() if k in self._viewers or now - v[1] <= REPORT_GAP_S}
                if len(kept) > MAX_REPORTERS:
                    kept = {k: v for k, v in kept.items() if k in self._viewers}
                self._reporting = kept

    def congested(self, now: float) -> None:
        """The link adapter judged the link congested at ``now``: losses until :data:`CALM_S` later do not end the
        long wave."""
        with self._lock:
            self._congested_at = now

    @property
    def reporters(self) -> int:
        """Consumers whose streaks are kept (diagnostics, tests)."""
        with self._lock:
            return len(self._reporting)

    def allowed(self, now: float) -> bool:
        """Whether every H.264 viewer reports, and none lost anything lately (see the module docstring); False with
        none."""
        with self._lock:
            if not self._viewers or now - self._loss_at < CLEAN_FOR_S:
                return False
            for name in self._viewers:
                first, last = self._reporting.get(name, (now, -1e18))
                if now - last > REPORT_GAP_S or last - first < REPORTING_FOR_S:
                    return False
            return True
