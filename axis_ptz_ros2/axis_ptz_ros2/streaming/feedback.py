"""Link adaptation: turn what the video's consumers *receive* into a bandwidth budget. ROS-free.

The stream node knows what it sends; only the consumers (the operator's station, across a weak link) know
what arrives and how late. They report it (``video/feedback``: frames and kbit/s received, and the delay
from the stream node's stamp to receipt). :class:`LinkAdapter` keeps a budget for the
:class:`~axis_ptz_ros2.streaming.budget.BandwidthController` so the stream never sends more than the link
delivers:

- **congested** — the queueing delay (the delay's p95 above its own minimum over ``base_window_s``: a clock
  offset between the hosts cancels out) exceeds ``delay_high_s``, or the consumer receives less than
  ``delivery_low`` of the frames sent: the budget drops to ``decrease`` × the rate the consumer received
  (the link's capacity just measured; halved instead when almost nothing arrives), at most once per
  ``decrease_hold_s``. When the congestion follows a step up from a rate the consumers received cleanly
  less than ``good_memory_s`` ago, the budget goes back to that rate (× ``good_margin``) instead: on a
  lossy link the received rate counts only *whole* frames, so a swamped link reads as far narrower than it is
  (a 2 Mbit/s link swamped at 1.9 Mbit/s delivered 0.4 Mbit/s of whole frames), and the rate just below
  was measured to work. One return per clean rate: if it congests too, the received rate decides;
- **clear** — the queueing delay is under ``delay_low_s`` and at least ``delivery_clear`` of the frames
  arrive: the budget (if there is one, or one started from ``grow_from_kbps`` where the sender can go past its
  start: H.264 with ``h264_max_bitrate_kbps`` above ``h264_bitrate_kbps``) grows
  by ``increase`` per report, but never past ``headroom`` × what is sent now or ``step_margin`` × the next
  better setting's predicted rate, so the stream climbs one step at a time and each step is judged; for
  ``probe_backoff_s`` after a congestion it stays under the rate that congested (doubling, up to
  ``probe_backoff_max_s``, when the next try congests again: a link that cannot carry the next step is
  not hammered with it); with ``probe_increase`` under ``increase`` (H.264), from ``decrease`` × that rate on it
  then grows by ``probe_increase`` once per ``climb_hold_s`` only, until what is sent reaches the rate that
  congested (the link carries it again: the rate is forgotten);
- **silent** — no report for ``silence_s`` (a cut link, or the consumer has gone): the budget is held at
  (``good_margin`` ×) what was being sent, so a healed link does not receive a burst at the full request and
  the ladder does not climb through the silence; after ``release_s`` the adapter lets go (0 = no limit from
  feedback).

Several consumers may report; the most constrained one decides (each one's last report is kept for
``silence_s``).

H.264 (:func:`.adapter_config.h264_adapter_config`) is judged differently. Every access unit that crosses counts
(the consumer reports what arrived, shown or not), and delivery is by bytes: what the consumer received against
what was sent. A lossy link delays the pictures behind each repaired loss by a repair round trip without any
queue, which reads as a p95 queueing delay of 100-200 ms on 2 Mbit/s with 2 % loss; judged by the MJPEG thresholds that
was "congested" report after report and the budget sank to its floor (124 kbit/s of a 1000 kbit/s request on
that link, weak-link bench at 8ff4f08). A queue that the sender builds grows past those tails within a report;
one that builds slowly is seen in the *median* delay (``median_high_s``): a queue delays every picture, a repair
only the few behind it. Growing back near a rate that congested, where the link's edge is, the *floor* (the smallest
delay of the report's last second, ``floor_high_s``) sees a standing queue a second before the median does, and
the budget leads what the encoder sends by at most ``probe_headroom``.
When the link itself steps down under a steady stream, for ``step_down_hold_s`` the budget stands at most at what that
decrease set and what the link delivered while full; that decrease itself goes under what arrived by the queue it
finds spread over ``drain_s`` (so the queue drains; the budget grows back to the hold's level once the link reads
clear), and a floor still over ``drain_floor_s`` ``drain_recheck_s`` after it (the queue not draining) decreases again
at once, once.
After a congestion its probing is careful: nothing grows for ``decrease_hold_s`` (a report in that time still
covers the congestion just answered), and the rate that congested is forgotten only when a consumer *receives*
it again, not when the sender's lagging window still reads it (docs/weak-link.md says what each rule cost without
it).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

from axis_ptz_ros2.streaming.adapter_config import AdapterConfig
from axis_ptz_ros2.streaming.meter import ConsumerCounts

__all__ = ["Decision", "FeedbackReport", "LinkAdapter"]


@dataclass(frozen=True, slots=True)
class FeedbackReport:
    """One consumer's measurement over its window (delays in seconds, rates as received)."""

    consumer: str
    frames: int
    fps: float
    kbps: float
    delay_p95_s: float
    delay_min_s: float  # smallest delay seen over a longer window (clock offset + fixed transmission delay)
    gap_s: float = 0.0  # time since that consumer's last frame
    window_s: float = 1.0  # the window ``frames``/``fps``/``kbps`` cover
    lost: int = 0  # H.264: access units that never arrived (pts gaps), a running count since it began watching
    delay_p50_s: float = 0.0  # median delay in the window; 0 = not measured (a consumer that does not fill it)
    delay_floor_s: float = 0.0  # smallest delay in the window's last half; 0 = not measured


@dataclass(frozen=True, slots=True)
class Decision:
    """What :meth:`LinkAdapter.report` concluded (for diagnostics and logs)."""

    budget_kbps: float
    state: str  # "congested", "clear", "steady", "silent", "released", "off"
    queue_delay_s: float  # the deciding consumer's p95 delay over its minimum
    delivery: float
    median_queue_s: float = 0.0  # its median delay over its minimum (0: not reported)
    floor_queue_s: float = 0.0  # the largest floor over its minimum among the consumers (0: not reported)


class LinkAdapter:
    """A bandwidth budget that follows what the consumers receive (see the module docstring)."""

    def __init__(self, config: AdapterConfig | None = None) -> None:
        """Start without a budget (0 = no limit) until the first report says otherwise."""
        self.config = config or AdapterConfig()
        self._budget = 0.0
        self._last_decrease = -1e18
        self._last_report = -1e18
        self._reports: dict[str, tuple[float, FeedbackReport]] = {}
        self._bad_kbps = 0.0  # what was sent when the link last congested ...
        self._drained_kbps = 0.0  # ... and what the consumers received at its last congested report (the link full)
        self._bad_until = -1e18  # ... and until when not to try it again
        self._backoff = self.config.probe_backoff_s
        self._good: deque[tuple[float, float]] = deque()  # (when, what was sent) of the recent clear reports
        self._sent_kbps = 0.0  # what was sent at the last report
        self._last_climb = -1e18  # when the budget last grew past ``grow_from_kbps``
        self._lost = ConsumerCounts()  # each consumer's running count of access units lost, at its last report
        self._clear_since_decrease = True  # a clear report since the last decrease (else a decrease is the same drain)
        self._hold_until = -1e18  # the link stepped down: nothing over ``_hold_kbps`` and the drained rate until then
        self._hold_kbps = 0.0
        self._rechecked = False  # the one early decrease of a step down (``drain_floor_s``) was made
        self.state = "off"

    @property
    def budget_kbps(self) -> float:
        """The budget to enforce (kbit/s); 0 = the link has not asked for one."""
        return self._budget

    def reset(self) -> None:
        """Forget everything (adaptation switched off)."""
        self._budget = 0.0
        self._reports.clear()
        self._last_report = -1e18
        self._good.clear()
        self._lost.forget()
        self._hold_until, self._hold_kbps, self._rechecked = -1e18, 0.0, False
        self.state = "off"

    def heard(self, now: float) -> None:
        """A consumer's report arrived that the sender does not judge (e.g. its window still holds a switch of
        settings): the link is alive, so this is no silence."""
        self._last_report = max(self._last_report, now)

    def report(
        self,
        now: float,
        report: FeedbackReport,
        sent_fps: float,
        sent_kbps: float,
        step_up_kbps: float = 0.0,
        grow_from_kbps: float = 0.0,
    ) -> Decision:
        """Take one consumer's report (``now`` = monotonic seconds at the sender, ``sent_*`` = what the
        sender measured over about the same window, ``step_up_kbps`` = the predicted rate of the next better
        setting, 0 if none); returns the decision with the new budget.

        ``grow_from_kbps`` > 0: the sender may go past what it sends without a budget (H.264 with a ceiling above
        its start bitrate), so a clear report starts a budget from this rate and grows it as usual, past it at most
        once per ``climb_hold_s``; 0 (MJPEG: the request is the best there is) leaves a clear link without a
        budget."""
        cfg = self.config
        self._last_report = now
        self._sent_kbps = sent_kbps
        self._reports[report.consumer] = (now, report)
        for name, (t, _r) in list(self._reports.items()):
            if now - t > cfg.silence_s:
                del self._reports[name]
        # access units lost since this consumer's last report (its first report, or a restarted count: none)
        lost = self._lost.grew(report.consumer, report.lost)
        worst = max(
            (r for _t, r in self._reports.values()),
            key=lambda r: (self._queue_delay(r), -self._judge_delivery(r, sent_fps, sent_kbps)),
        )
        queue = self._queue_delay(worst)
        median = max((self._over_min(r, r.delay_p50_s) for _t, r in self._reports.values()), default=0.0)
        floor = max((self._over_min(r, r.delay_floor_s) for _t, r in self._reports.values()), default=0.0)
        delivery = self._judge_delivery(worst, sent_fps, sent_kbps)
        received = min(r.kbps for _t, r in self._reports.values())
        # an access unit lost with a queue standing: the queue outlasted the writer's history (congestion); lost
        # with none (under what reads clear), it is the link's random loss repaired too late: no cut, no growth
        lost_news = cfg.lost_congested > 0 and lost >= cfg.lost_congested
        lossy = lost_news and queue >= cfg.delay_low_s
        queued = cfg.median_high_s > 0 and median > cfg.median_high_s
        # judged while probing near a rate that congested: there the frames' size hardly changes within the floor's
        # reference window, while a ramp from a lower rate raises the floor by its larger frames' own transmission
        # (the step bench's 2 Mbit/s ramp, debug log: 15 ms at 1208 kbit/s sent 6 s after 727, no queue)
        near = 0 < self._careful_from() <= self._budget
        edge = cfg.floor_high_s > 0 and floor > cfg.floor_high_s and near
        if queue > cfg.delay_high_s or delivery < cfg.delivery_low or lossy or queued or edge:
            state = "congested"
            self._drained_kbps = received  # the link full: what it delivers is its capacity now
            since = now - self._last_decrease
            # the link stepped down, and a queue still stands a while after the decrease, every picture waiting in it:
            # that decrease was not under what the link carries now (its received rate's window began before the
            # step). Once per step down: a sender that follows its budget slowly (a camera's own encoder) or a robot
            # whose CPU stalls keeps the floor up too, and repeated early decreases took the budget to its floor
            # (batch at e528466: the current-Axis persona passed through, 1540 -> 100 kbit/s on 2 Mbit/s)
            stuck = (
                cfg.drain_floor_s > 0
                and now < self._hold_until
                and not self._rechecked
                and not self._clear_since_decrease
                and since >= cfg.drain_recheck_s
                and floor > cfg.drain_floor_s
            )
            if stuck:
                self._rechecked = True
            if since >= cfg.decrease_hold_s or stuck:
                current = self._budget if self._budget > 0 else max(sent_kbps, received)
                # the link delivered ``received``: stay a margin under it; if almost nothing arrives (the sender
                # swamps the link), halve until something does
                delivered = worst.frames >= 2 and received > 0
                new = cfg.decrease * min(received, current) if delivered else 0.5 * current
                good = [k for t, k in self._good if now - t <= cfg.good_memory_s and k < cfg.decrease * sent_kbps]
                if good:  # a step up congested: the rate before it was received cleanly, go back there
                    new = max(new, min(cfg.good_margin * max(good), cfg.decrease * sent_kbps))
                probe = 0 < grow_from_kbps < current and sent_kbps >= grow_from_kbps
                steady = self._steady_before(now, sent_kbps)
                if probe and not steady:
                    # a probe past the start (H.264 above h264_bitrate_kbps) congested: back towards the start, the
                    # rate that runs without any feedback, one ``decrease`` step at most, not to what the swamped link
                    # delivered meanwhile (weak-link bench at 4d580ab: a probe to 1300 kbit/s fell to 280-600 kbit/s
                    # for 10 s); under the start, the received rate decides again. Not when this rate had been
                    # carried cleanly for ``stable_s``: the link changed, and its start may be more than it carries
                    # now (the 2 -> 1 Mbit/s step at 3b0f6ed, debug log: sending ~1260 kbit/s for 10 s, then
                    # congested with 796 received; back to the 1000 kbit/s start the queue stood 2.5 s more, until
                    # the next decrease to 364 kbit/s; the frame age was back under 100 ms 4.7 s after the step).
                    # Only when what was sent reached the start: a budget grown past it on a still scene while the
                    # encoder sent less (1 Mbit/s link at e5828d4, debug log: budget 1165, 773 kbit/s sent, 553
                    # received) went "back" to 932 kbit/s, above what was sent, and the queue stood 2.5 s more
                    new = max(new, min(grow_from_kbps, cfg.decrease * current))
                self._good.clear()
                self._budget = max(new, cfg.min_kbps)
                if steady and cfg.step_down_hold_s > 0:
                    self._hold_until, self._hold_kbps = now + cfg.step_down_hold_s, self._budget
                    self._rechecked = False
                    if cfg.drain_s > 0 and delivered:
                        # the queue that stood up while the link stepped down drains within ``drain_s``: the
                        # budget goes under what arrived by the queue's bits spread over that time (the hold's level
                        # stays: the budget grows back to it once the link reads clear). Not when (almost) nothing
                        # arrived: a cut link's reports read a queue as long as the cut and a rate of 0, which took the
                        # budget to its floor (batch at 2e23232: the first picture 1.78 s after a heal, 0.91 before)
                        share = min(cfg.decrease, max(cfg.drain_min_share, 1.0 - queue / cfg.drain_s))
                        self._budget = max(min(self._budget, share * min(received, current)), cfg.min_kbps)
                # remember the rate that congested; a new try soon after that congests again backs off longer.
                # A decrease with no clear report since the last one is the same congestion draining: the rate that
                # congested stays the highest of it (the drain's own lower rates are no limit of the link, and the
                # consumer receiving one of them is no sign that the link carries the first: 2 -> 1 Mbit/s step at
                # e5828d4, debug log: decreases at 1263, 918, 773 and 662 kbit/s, the last forgotten when 679 arrived,
                # the budget x1.2 per report to 2250, the age p95 near 100 ms to the end)
                draining = not self._clear_since_decrease
                again = not draining and now < self._bad_until + cfg.probe_backoff_s
                if not draining:
                    self._backoff = min(self._backoff * 2.0, cfg.probe_backoff_max_s) if again else cfg.probe_backoff_s
                self._bad_kbps = max(self._bad_kbps, sent_kbps, received) if draining else max(sent_kbps, received)
                self._clear_since_decrease = False
                self._bad_until = now + self._backoff
                self._last_decrease = now
        elif queue < cfg.delay_low_s and delivery >= cfg.delivery_clear and lost == 0:
            state = "clear"
            self._clear_since_decrease = True
            self._good.append((now, sent_kbps))
            while self._good and now - self._good[0][0] > cfg.good_memory_s:
                self._good.popleft()
            careful = 0.0 < cfg.probe_increase < cfg.increase
            settled = now - self._last_decrease >= cfg.decrease_hold_s
            if careful and 0 < self._bad_kbps <= received and settled:
                # the link now carries what congested it: nothing to be careful of. Judged by what arrived, not by
                # what was sent: the sender's window still holds the rate that congested for a report or two after
                # the decrease (weak-link bench at a2bf677, the 2 -> 1 Mbit/s step: the next report read "sent 894
                # kbit/s" against 856 that congested, the rate was forgotten and the budget went 594 -> 1350 kbit/s
                # in 2.5 s, ×1.2 per report, while the queue was still 240 ms)
                # Nor within ``decrease_hold_s`` of the decrease: a report there still covers the rate that congested
                # (the link's edge, found by the floor, is received in full: at 4d035e4 plus the floor rule, 736
                # kbit/s eased, the next report read 756 received, the rate was forgotten and the budget grew x1.2
                # per report from 634 to 1315 kbit/s into a 440 ms queue)
                self._bad_kbps = self._drained_kbps = 0.0
            base = self._budget if self._budget > 0 else grow_from_kbps
            if careful and now - self._last_decrease < cfg.decrease_hold_s:
                base = 0.0  # the report still covers the congestion just answered: no growth on it
            hold = 0.0
            if now < self._hold_until:
                # the link stepped down under a steady stream: growth past what it delivers now reaches the new edge
                # within seconds (2 -> 1 Mbit/s step at 78a1e7f, debug log: from 637 kbit/s by 5 % per 2 s to 766 sent
                # 16 s after the step, a 200 ms queue; the 1 s windows' age p95 at 106-130 ms already from 655 kbit/s
                # sent, the repairs' tails on a fuller link). A link that stepped down seldom steps back up within
                # seconds: until the hold ends nothing over what the link delivered while full (the drain's last
                # congested report; a decrease's received rate covers a window from before the step, 762-893 kbit/s
                # where 650-700 run clean, debug logs), or over what the decrease set when that is less
                hold = min(self._drained_kbps, self._hold_kbps) if self._drained_kbps > 0 else self._hold_kbps
                self._budget = max(min(self._budget, hold), cfg.min_kbps)
            # near the rate that last congested (the back-off over), growth by ``probe_increase``; so from what
            # the link delivered while full, too, where that is less: a link that stepped down carries
            # less than ``decrease`` x the rate that congested it (2 -> 1 Mbit/s step at 859821a, debug log: 1302
            # kbit/s congested, 599 delivered at the drain's last congested report; x1.2 per report from 486 to
            # 1042, 812 sent, congested again, 11 s)
            careful_from = self._careful_from()
            probing = careful and base >= careful_from > 0
            # past the start, and when probing, one step per report window: each is judged on a window of its own
            # (the sender's rate follows the budget at once, and a report covers the last ``window_s``)
            climbing = probing or (grow_from_kbps > 0 and base >= grow_from_kbps)
            if climbing and now - self._last_climb < cfg.climb_hold_s:
                base = 0.0
            elif climbing:
                self._last_climb = now
            if base > 0:
                ceiling = max(cfg.headroom * max(sent_kbps, received, cfg.min_kbps), cfg.step_margin * step_up_kbps)
                if now < self._bad_until and self._bad_kbps > 0:
                    ceiling = min(ceiling, cfg.decrease * self._bad_kbps)
                if probing and cfg.probe_headroom > 0:
                    # a probe is judged at the rate the encoder sends: a budget far over it (x264 on a still scene
                    # sends 65 % of a 1112 kbit/s target) is no probe, and lets a change of scene jump past the edge
                    # at once (1 Mbit/s + 2 %, debug log at 4d035e4 plus the floor rule: sent 728 -> 794 kbit/s
                    # within a second under a budget of 1112, a 450 ms queue)
                    ceiling = min(ceiling, cfg.probe_headroom * max(sent_kbps, received, cfg.min_kbps))
                if hold > 0:
                    ceiling = min(ceiling, hold)
                self._budget = min(base * (cfg.probe_increase if probing else cfg.increase), max(ceiling, base))
        else:
            state = "steady"
        self.state = state
        return Decision(self._budget, state, queue, delivery, median, floor)

    def tick(self, now: float) -> Decision:
        """Called periodically without a report: hold the budget through a silence, release it after
        ``release_s``."""
        cfg = self.config
        silent_for = now - self._last_report
        if self._budget > 0 and silent_for > cfg.release_s:
            self._budget = 0.0
            self._reports.clear()
            self.state = "released"
        elif self._budget > 0 and silent_for > cfg.silence_s:
            if self.state != "silent" and self._sent_kbps > 0:
                # hold what was sent: room under a grown budget would let the ladder climb blind
                self._budget = max(min(self._budget, cfg.good_margin * self._sent_kbps), cfg.min_kbps)
            self.state = "silent"
        return Decision(self._budget, self.state, 0.0, 1.0)

    def _careful_from(self) -> float:
        """The rate from which growth is careful (``probe_increase``): a margin under the rate that last congested,
        or what the link delivered while full where that is less: a draining queue arrives at the link's capacity,
        so nothing past it is safe to grow into quickly (the 2 -> 1 Mbit/s step at 4d035e4, debug log: 732 kbit/s
        arrived at the drain's last congested report; x1.2 per report to 1.15 x that, 844, and the queue stood
        again at 736 kbit/s sent). 0 when nothing congested."""
        cfg = self.config
        careful_from = cfg.decrease * self._bad_kbps
        if self._drained_kbps > 0:
            careful_from = min(careful_from, self._drained_kbps)
        return careful_from

    def _steady_before(self, now: float, sent_kbps: float) -> bool:
        """Whether the clear reports of the last ``stable_s`` and more (since the last congestion, within
        ``good_memory_s``) all saw at least ``stable_share`` of ``sent_kbps`` sent: a steady stream, not a probe."""
        cfg = self.config
        recent = [(t, k) for t, k in self._good if now - t <= cfg.good_memory_s]
        if not recent or now - recent[0][0] < cfg.stable_s:
            return False
        return all(k >= cfg.stable_share * sent_kbps for _t, k in recent)

    @staticmethod
    def _queue_delay(r: FeedbackReport) -> float:
        if r.frames == 0:
            return r.gap_s
        return max(r.delay_p95_s - r.delay_min_s, 0.0)

    @staticmethod
    def _over_min(r: FeedbackReport, delay_s: float) -> float:
        """One of the report's delays (its median, its floor) over its minimum; 0 when nothing arrived (the gap
        judges that) or the consumer did not measure it (0)."""
        if r.frames == 0 or delay_s <= 0:
            return 0.0
        return max(delay_s - r.delay_min_s, 0.0)

    def _judge_delivery(self, r: FeedbackReport, sent_fps: float, sent_kbps: float) -> float:
        """Fraction delivered: of the bytes sent (``delivery_by_bytes``), else of the frames."""
        cfg = self.config
        if cfg.delivery_by_bytes:
            if sent_kbps <= 0 or sent_fps * r.window_s < cfg.min_expected_frames:
                return 1.0
            return min(r.kbps / sent_kbps, 1.0)
        return self._delivery(r, sent_fps, cfg.min_expected_frames)

    @staticmethod
    def _delivery(r: FeedbackReport, sent_fps: float, min_expected: int) -> float:
        """Fraction of the frames sent that arrived; 1.0 when too few were expected to judge (a window
        holding 2 frames at 2 fps would read 0.5 for one frame early or late)."""
        if sent_fps <= 0 or sent_fps * r.window_s < min_expected:
            return 1.0
        return min(r.fps / sent_fps, 1.0)
