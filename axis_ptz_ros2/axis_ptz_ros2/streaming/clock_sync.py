"""Camera time → host time for the frames of an RTSP stream, never backwards (ROS-free, stdlib only).

A frame's RTP timestamp says when the camera captured it on the camera's own clock (90 kHz, random origin); the
RTCP sender reports tie that clock to the camera's wall clock (NTP), which may be anything (30 s behind, stepped
by NTP mid-stream). Stamping frames with the camera's wall clock makes stamps jump whenever that clock is off or
moves; stamping with the arrival time adds the queueing delay of each frame. :class:`StreamClock` does neither:

* :class:`LowerEnvelope` maps a camera timeline (the unwrapped RTP time, in ns) to the host clock from the
  arrival times: every frame gives ``arrival − camera time`` = clock offset + the fixed latency (encoder, network)
  + a queueing delay ≥ 0. The lower envelope of these samples drops the queueing delay: the minimum per
  :attr:`~LowerEnvelope.bucket_s` of camera time, over a window of :attr:`~LowerEnvelope.window_s`; the drift
  of the camera's crystal is the Theil–Sen slope over those minima (a median of pairwise slopes: a few buckets of
  long delays do not tilt it), clamped to ±``max_drift_ppm``; the line is then lowered until no minimum lies
  under it. A sample under the line lowers it at once (less delay than ever seen).
* A step of the camera timeline (or of the host clock) is a sample more than ``step_s`` off the line: under it,
  the estimator restarts at once; over it by about the same amount (within ``step_s / 2``) for ``confirm_s`` of
  arrivals in a row, it restarts at the new level. A burst of late frames after a network stall is no step: its
  delay falls frame by frame as the queue drains, and its frames keep the line's stamps (their capture time);
  the frames of a real step up are stamped from the old line (then held above the previous stamp) until it is
  confirmed.
* A frame arrives after its capture by the encoder's latency + the network's; an RTCP sender report (its RTP
  time is the moment it was sent) by the network's alone. :meth:`StreamClock.sender_report` takes the reports'
  arrivals: the most any recent report lies under the frames' line (at most :data:`MAX_ENCODER_LATENCY_S`) is
  the encoder's latency, taken off every stamp: with reports, a stamp is the capture time (+ the network's least
  delay); without, the capture time + the camera's least latency.
* Stamps are host time (the clock the arrival times are on: :func:`time.time_ns`), strictly increasing per
  stream (a stamp is never at or below the previous one, across sessions of the same stream too), except when the
  host clock itself steps (:meth:`StreamClock.host_clock_stepped`): then they move with it, backwards too, as every
  other stamp on the host does.
* The camera's wall-clock offset (``host − camera``, from the sender-report time of each frame) is kept for
  diagnostics: :attr:`StreamClock.camera_offset_ns`; it includes the fixed latency (tens of ms), so it is the
  offset to well within 0.1 s. :meth:`StreamClock.take_offset_warning` is True once when it is beyond
  :data:`OFFSET_WARN_S` (the camera's clock is not set: "set NTP on the camera").
"""

from __future__ import annotations

import collections
import statistics
from dataclasses import dataclass
from typing import Final

OFFSET_WARN_S: Final = 1.0  #: |camera wall clock − host clock| beyond this: warn (once)
CLOCK_RATE: Final = 90_000  #: RTP clock of H.264 video
MAX_ENCODER_LATENCY_S: Final = 1.0  #: a sender report further under the frames' line is inconsistent: ignored
_NS: Final = 1_000_000_000


@dataclass(slots=True)
class _Point:
    camera_ns: int
    offset_ns: int  # arrival − camera


class LowerEnvelope:
    """``host ≈ camera + offset(camera)`` from ``(camera_ns, arrival_ns)`` samples (see the module notes)."""

    def __init__(
        self,
        *,
        window_s: float = 60.0,
        bucket_s: float = 1.0,
        step_s: float = 1.0,
        confirm_s: float = 2.0,
        max_drift_ppm: float = 500.0,
    ) -> None:
        if not (0 < bucket_s < window_s and step_s > 0 and confirm_s >= 0 and max_drift_ppm >= 0):
            raise ValueError("need 0 < bucket_s < window_s, step_s > 0, confirm_s >= 0, max_drift_ppm >= 0")
        self.window_s, self.bucket_s, self.step_s, self.confirm_s = window_s, bucket_s, step_s, confirm_s
        self.max_drift_ppm = max_drift_ppm
        self.steps = 0  #: restarts on a step of either clock
        self._bucket_ns = int(bucket_s * _NS)
        self._window_ns = int(window_s * _NS)
        self._step_ns = int(step_s * _NS)
        self._confirm_ns = int(confirm_s * _NS)
        self._reset()

    def _reset(self) -> None:
        self._closed: list[_Point] = []  # the minimum of each closed bucket, oldest first
        self._open: _Point | None = None  # the minimum of the bucket being filled
        self._open_index: int | None = None
        self._slope = 0.0  # offset change per camera ns (drift)
        self._ref_ns = 0  # camera time of the line's reference point
        self._at_ref: int | None = None  # offset at _ref_ns (None: no sample yet)
        self._high_since: int | None = None  # arrival of the first of the samples over the line in a row
        self._high_min: _Point | None = None

    def shift(self, delta_ns: int) -> None:
        """The host clock stepped by ``delta_ns``: every sample's arrival, so the line, moves with it (no restart)."""
        self._closed = [_Point(p.camera_ns, p.offset_ns + delta_ns) for p in self._closed]
        if self._open is not None:
            self._open = _Point(self._open.camera_ns, self._open.offset_ns + delta_ns)
        if self._at_ref is not None:
            self._at_ref += delta_ns
        if self._high_since is not None:
            self._high_since += delta_ns
        if self._high_min is not None:
            self._high_min = _Point(self._high_min.camera_ns, self._high_min.offset_ns + delta_ns)

    @property
    def ready(self) -> bool:
        """Whether a sample has been seen (the line exists)."""
        return self._at_ref is not None

    @property
    def drift_ppm(self) -> float:
        """The camera clock's rate against the host's, in ppm (positive: the host clock runs faster)."""
        return self._slope * 1e6

    def offset_ns(self, camera_ns: int) -> int | None:
        """``host − camera`` at ``camera_ns`` on the line (None before the first sample)."""
        if self._at_ref is None:
            return None
        return self._at_ref + round(self._slope * (camera_ns - self._ref_ns))

    def add(self, camera_ns: int, arrival_ns: int) -> int:
        """Take one sample; return the host time of ``camera_ns`` (the lower envelope; while a step up is being
        confirmed, the running minimum of the samples over the line)."""
        y = arrival_ns - camera_ns
        line = self.offset_ns(camera_ns)
        if line is None or y < line - self._step_ns:
            if line is not None:
                self.steps += 1
            self._reset()
            self._start(camera_ns, y)
            return camera_ns + y
        if y > line + self._step_ns:
            # late by more than a step: a queue (a burst after a stall drains: the delay falls frame by frame)
            # or a step (the delay stays put): stamped from the line until it has stayed put for confirm_s
            run = self._high_min
            if run is None or self._high_since is None or abs(y - run.offset_ns) > self._step_ns // 2:
                self._high_since, self._high_min = arrival_ns, _Point(camera_ns, y)
            elif y < run.offset_ns:
                self._high_min = _Point(camera_ns, y)
            low = self._high_min
            assert low is not None
            assert self._high_since is not None
            if arrival_ns - self._high_since >= self._confirm_ns:
                self.steps += 1
                self._reset()
                self._start(low.camera_ns, low.offset_ns)
                self._take(camera_ns, y)
                return camera_ns + min(y, low.offset_ns)
            return camera_ns + line
        self._high_since = self._high_min = None
        self._take(camera_ns, y)
        offset = self.offset_ns(camera_ns)
        assert offset is not None
        return camera_ns + offset

    def _start(self, camera_ns: int, y: int) -> None:
        self._open_index = camera_ns // self._bucket_ns
        self._open = _Point(camera_ns, y)
        self._ref_ns, self._at_ref, self._slope = camera_ns, y, 0.0

    def _take(self, camera_ns: int, y: int) -> None:
        index = camera_ns // self._bucket_ns
        if index != self._open_index or self._open is None:
            if self._open is not None:
                self._closed.append(self._open)
            self._open_index, self._open = index, _Point(camera_ns, y)
            self._refit(camera_ns)
        elif y < self._open.offset_ns:
            self._open = _Point(camera_ns, y)
        line = self.offset_ns(camera_ns)
        assert line is not None
        if y < line:  # less delay than the line allows: lower it to this sample
            self._ref_ns, self._at_ref = camera_ns, y

    def _refit(self, now_ns: int) -> None:
        """Drop buckets out of the window; the Theil–Sen slope over the minima; the line under all of them."""
        keep = [p for p in self._closed if 0 <= now_ns - p.camera_ns <= self._window_ns]
        self._closed = keep
        points = [*keep, *([self._open] if self._open is not None else [])]
        if len(keep) >= 4 and keep[-1].camera_ns - keep[0].camera_ns >= 3 * self._bucket_ns:
            slopes = [
                (b.offset_ns - a.offset_ns) / (b.camera_ns - a.camera_ns)
                for i, a in enumerate(keep)
                for b in keep[i + 1 :]
                if b.camera_ns != a.camera_ns
            ]
            limit = self.max_drift_ppm * 1e-6
            self._slope = max(-limit, min(limit, statistics.median(slopes))) if slopes else 0.0
        self._ref_ns = now_ns
        self._at_ref = min(p.offset_ns + round(self._slope * (now_ns - p.camera_ns)) for p in points)


class StreamClock:
    """Stamps for one stream's frames: host time, strictly increasing (see the module notes). Not thread-safe."""

    def __init__(self, clock_rate: int = CLOCK_RATE, warn_offset_s: float = OFFSET_WARN_S, **envelope: float) -> None:
        """``envelope``: :class:`LowerEnvelope`'s keyword arguments."""
        if clock_rate <= 0:
            raise ValueError("clock_rate must be positive")
        self.clock_rate = clock_rate
        self.warn_offset_ns = int(warn_offset_s * _NS)
        self.envelope = LowerEnvelope(**envelope)
        self.camera_offset_ns: int | None = None  #: host − camera wall clock (None before a sender report)
        self.clamped = 0  #: stamps raised to stay above the previous one
        self.encoder_latency_ns = 0  #: what the sender reports say the frames' line is late by (capture → send)
        self._last_stamp: int | None = None
        self._rtp: int | None = None
        self._ticks = 0  # the unwrapped RTP time
        self._warned = False
        self._reports: collections.deque[tuple[int, int]] = collections.deque(maxlen=64)  # (rtp, arrival_ns)
        self._steps = 0

    def new_session(self) -> None:
        """A new RTSP session of the same stream: a new RTP origin; stamps still never go below the last one."""
        self._rtp = None
        self._ticks = 0
        self._reports.clear()
        self._steps = 0
        self.envelope = LowerEnvelope(
            window_s=self.envelope.window_s,
            bucket_s=self.envelope.bucket_s,
            step_s=self.envelope.step_s,
            confirm_s=self.envelope.confirm_s,
            max_drift_ppm=self.envelope.max_drift_ppm,
        )

    @property
    def drift_ppm(self) -> float:
        """The camera's RTP clock against the host clock (ppm)."""
        return self.envelope.drift_ppm

    @property
    def offset_warning(self) -> bool:
        """Whether the camera's wall clock is more than the warning threshold off the host clock."""
        off = self.camera_offset_ns
        return off is not None and abs(off) > self.warn_offset_ns

    def take_offset_warning(self) -> bool:
        """True the first time :attr:`offset_warning` holds (warn once), False after."""
        if self._warned or not self.offset_warning:
            return False
        self._warned = True
        return True

    def host_clock_stepped(self, delta_ns: int) -> None:
        """The host's wall clock stepped by ``delta_ns`` (:class:`~.wall_clock.WallClockSteps`): the stamps follow
        it at once, as every other stamp on this host does, backwards too (never frozen at the last stamp until the
        clock catches up with it), and the line moves with it: no restart, no stamps from a stale line."""
        self.envelope.shift(delta_ns)
        self._reports = collections.deque(((rtp, t + delta_ns) for rtp, t in self._reports), self._reports.maxlen)
        if self._last_stamp is not None:
            self._last_stamp += delta_ns
        if self.camera_offset_ns is not None:
            self.camera_offset_ns += delta_ns

    def sender_report(self, rtp_timestamp: int, arrival_ns: int) -> None:
        """An RTCP sender report of this session (its RTP time) arrived at ``arrival_ns`` (host clock)."""
        item = (rtp_timestamp & 0xFFFFFFFF, arrival_ns)
        if not self._reports or self._reports[-1] != item:
            self._reports.append(item)

    def _encoder_latency(self, arrival_ns: int) -> int:
        """The most a recent sender report lies under the frames' line (0 without one)."""
        if self.envelope.steps != self._steps:  # a step: the reports were on the old timeline
            self._steps = self.envelope.steps
            self._reports.clear()
        window_ns = int(self.envelope.window_s * _NS)
        while self._reports and arrival_ns - self._reports[0][1] > window_ns:
            self._reports.popleft()
        if self._rtp is None:
            return 0
        best = 0
        for rtp, arrived in self._reports:
            diff = (rtp - self._rtp) & 0xFFFFFFFF
            media_ns = (self._ticks + (diff - (1 << 32) if diff >= 1 << 31 else diff)) * _NS // self.clock_rate
            line = self.envelope.offset_ns(media_ns)
            if line is None:
                continue
            under = media_ns + line - arrived
            if under <= MAX_ENCODER_LATENCY_S * _NS:
                best = max(best, under)
        return best

    def stamp(self, rtp_timestamp: int, arrival_ns: int, camera_ns: int | None = None) -> int:
        """The host-time stamp of a frame with ``rtp_timestamp`` that arrived at ``arrival_ns`` (host clock);
        ``camera_ns``: its capture time on the camera's wall clock (sender reports), for the offset only."""
        rtp = rtp_timestamp & 0xFFFFFFFF
        if self._rtp is not None:
            diff = (rtp - self._rtp) & 0xFFFFFFFF
            self._ticks += diff - (1 << 32) if diff >= 1 << 31 else diff
        self._rtp = rtp
        media_ns = self._ticks * _NS // self.clock_rate
        host = self.envelope.add(media_ns, arrival_ns)
        self.encoder_latency_ns = self._encoder_latency(arrival_ns)
        host -= self.encoder_latency_ns
        if camera_ns is not None:
            self.camera_offset_ns = host - camera_ns
        if self._last_stamp is not None and host <= self._last_stamp:
            host = self._last_stamp + 1
            self.clamped += 1
        self._last_stamp = host
        return host
