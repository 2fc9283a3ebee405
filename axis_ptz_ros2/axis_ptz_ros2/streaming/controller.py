"""The video controller: the one owner of the video parameters in effect. ROS-free.

It holds what is asked for (:class:`~.video_types.VideoSettings`, the stream node's live parameters field for
field; what is in effect and the records of its decisions are :mod:`.video_types` too), the camera's resolution
list once learned, the bandwidth budget (:class:`~.budget.BandwidthController`) and the link adapter
(:class:`~.feedback.LinkAdapter`) under one lock, and derives from them the one :class:`VideoParams` to stream
with (:attr:`VideoController.current`). The stream node only feeds it (parameter sets, consumers' reports,
frames, what discovery learned) and reads it (what to request from the camera, what to publish). Every change of
what is in effect, or of what is advertised with it, is announced through ``on_change()`` (serialised: read
:meth:`VideoController.state` in it, and the last announcement describes the latest state).

Policy that lives here:

* resolution ``""`` = the largest size the camera lists (704x576 while it cannot list them; the request itself is
  built by :mod:`.video_request`);
* requests are validated against the camera's own list once known (never an assumed one);
* the budget in force is the tighter of the hand-set ``max_bitrate_kbps`` and the link adapter's, in either codec
  (what :meth:`VideoController.state` advertises);
* a consumer's report is judged only when it says something about the link (:meth:`VideoController.feedback`);
* the budget is re-judged at most every :data:`BUDGET_PERIOD_S` on the frame path.

The codec (``codec``: ``mjpeg`` | ``h264``) is policy here too. In ``h264`` mode the camera is asked for its best
quality (compression 0) at the requested size and rate, the MJPEG budget ladder stands still, and the budget in
force drives the encoder's bitrate and VBV buffer instead (:meth:`VideoController.h264_settings`; how, in
:mod:`.h264_policy`). Consumers' reports are then judged against the H.264 bytes sent
(:meth:`VideoController.on_h264_frame`), not the camera's JPEGs. No ladder step announces a change of the budget
there: it is announced (as ``bandwidth_budget``) when it moves by :data:`BUDGET_ANNOUNCE_SLACK` or more from the
one last announced, or comes or goes.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Collection
from dataclasses import replace

from axis_ptz_ros2.media.h264_settings import H264Settings
from axis_ptz_ros2.streaming.adapter_config import AdapterConfig, h264_adapter_config
from axis_ptz_ros2.streaming.budget import AXIS214_PAL_RESOLUTIONS, BandwidthController
from axis_ptz_ros2.streaming.feedback import Decision, FeedbackReport, LinkAdapter
from axis_ptz_ros2.streaming.h264_policy import (
    H264_BUDGET_FRACTION,
    H264_FIELDS,
    check_h264,
    h264_target_kbps,
    h264_vbv_kbit,
)
from axis_ptz_ros2.streaming.meter import BitrateMeter
from axis_ptz_ros2.streaming.mjpeg_share import MjpegShare, split_kbps
from axis_ptz_ros2.streaming.report_screen import ReportScreen
from axis_ptz_ros2.streaming.still import ExtraBytes, StillWindow
from axis_ptz_ros2.streaming.video_request import LINK_FIELDS, VIDEO_FIELDS, camera_request, share_request
from axis_ptz_ros2.streaming.video_types import BudgetStep, LinkJudgement, VideoSettings, VideoState
from axis_ptz_ros2.vapix.errors import InvalidArgument
from axis_ptz_ros2.vapix.models import Resolution, VideoParams

#: s: the budget is re-judged at most this often on the frame path
BUDGET_PERIOD_S = 0.25
#: the largest share of the budget a still on demand may take from the live stream while it counts (on_still)
STILL_SHARE = 0.5
#: h264 mode: a change of the budget in force smaller than this fraction of the one last announced is not announced
BUDGET_ANNOUNCE_SLACK = 0.1


class VideoController:
    """The one owner of the video parameters in effect (see the module docstring); thread-safe."""

    def __init__(
        self,
        settings: VideoSettings,
        meter: BitrateMeter,
        *,
        camera: int = 1,
        on_change: Callable[[], None] | None = None,
        clock: Callable[[], float] = time.monotonic,
        h264_possible: bool = True,
    ) -> None:
        """Raises ValueError with the reason if ``settings`` ask for what no camera could stream.
        ``h264_possible``: whether H.264 can be produced here (:meth:`set_h264_possible`)."""
        self._h264_possible = h264_possible
        self._lock = threading.Lock()
        self._notify_lock = threading.Lock()
        self._meter = meter
        self._camera = camera
        self._on_change = on_change
        self._clock = clock
        self._resolutions: tuple[Resolution, ...] | None = None  # the camera's list, once learned
        reason = self.check(settings, VIDEO_FIELDS)
        if reason:
            raise ValueError(reason)
        self._settings = settings
        self._h264_meter = BitrateMeter(meter.window_s)  # the H.264 bytes sent, in h264 mode
        self._extra = ExtraBytes(meter.window_s)  # stills sent on the same link (streaming/still.py)
        self._still = StillWindow()  # h264 mode: a still crossing the link
        self._link = LinkAdapter(_adapter_config(settings, self.h264))
        self._budget = BandwidthController(
            self._request(settings),
            self._effective_budget(),
            AXIS214_PAL_RESOLUTIONS,
            settings.budget_config(),
        )
        self._current = self._budget.current
        self._source = "startup"
        self._screen = ReportScreen()  # which consumer reports are judged
        self._budget_check = -1e18
        self._decision: Decision | None = None
        self._announced_kbps = self._budget_kbps()  # the budget in force at the last announcement
        self._stream_size: Resolution | None = None  # h264: the size a camera's own H.264 is asked for (auto)
        #: h264 mode: the MJPEG topic's own camera stream and its share of the budget (:mod:`.mjpeg_share`)
        self.mjpeg = MjpegShare(
            self._share_request(settings),
            self.video_kbps,
            max_compression=int(settings.budget_max_compression),
            window_s=meter.window_s,
            clock=clock,
        )

    # -- reading -------------------------------------------------------------------------------------------
    @property
    def current(self) -> VideoParams:
        """The parameters to stream with now (lock-free: one immutable value)."""
        return self._current

    @property
    def settings(self) -> VideoSettings:
        """What is asked for."""
        return self._settings

    @property
    def resolutions_known(self) -> bool:
        """Whether the camera's own resolution list has been learned."""
        return self._resolutions is not None

    def set_stream_size(self, size: Resolution | None) -> None:
        """h264 mode: the size a camera's own H.264 is asked for when it is not :attr:`current`'s (resolution auto,
        passed through: :mod:`.passthrough_size` picks it by the bitrate), shown in :meth:`state` (``video/params``,
        diagnostics); None = :attr:`current`'s. A change is announced, as ``bandwidth_budget`` after the first."""
        with self._lock:
            if size == self._stream_size:
                return
            if size is not None and self._stream_size is not None:
                self._source = "bandwidth_budget"
            self._stream_size = size
        self._announce()

    @property
    def h264(self) -> bool:
        """Whether H.264 is in effect: the codec asked for is H.264 and it can be produced here (the one place that
        decides: without it the MJPEG topic is the main stream at the request, on the MJPEG ladder, and no MJPEG share
        runs)."""
        return self._settings.codec == "h264" and self._h264_possible

    def set_h264_possible(self, possible: bool) -> None:
        """Whether H.264 can be produced here (PyAV usable to transcode, or the camera's own passed through). A
        change while the codec asked for is H.264 switches what is in effect as a change of codec would (announced,
        the cause left as it was)."""
        with self._lock:
            if possible == self._h264_possible:
                return
            was = self.h264
            self._h264_possible = possible
            if self.h264 == was:
                return
            self._codec_switched(self._clock())
            self._budget.configure(requested=self._request(self._settings), now=self._clock())
            self._current = self._budget.current
        self._announce()

    def video_kbps(self) -> int:
        """h264 mode: what the budgets in force let the video have as a whole, kbit/s (:func:`h264_target_kbps`;
        lock-free: one read of the link's budget)."""
        s = self._settings
        link = self._link.budget_kbps if s.adapt_to_link else 0.0
        return h264_target_kbps(s.h264.bitrate_kbps, s.h264.max_bitrate_kbps, link, float(s.max_bitrate_kbps))[0]

    def h264_settings(self) -> H264Settings:
        """What the H.264 encoder (or the camera, passed through) is to do now: :func:`h264_target_kbps` of the
        budgets in force (the hand-set one and the link's), less the MJPEG stream's share while it runs
        (:func:`~.mjpeg_share.split_kbps`)."""
        s = self._settings
        with self._lock:
            link = self._link.budget_kbps if s.adapt_to_link else 0.0
        kbps, ceiling = h264_target_kbps(s.h264.bitrate_kbps, s.h264.max_bitrate_kbps, link, float(s.max_bitrate_kbps))
        kbps = split_kbps(kbps, self.mjpeg.active)[0]
        kbps = self._still.cap(self._clock(), kbps)
        return replace(
            s.h264,
            bitrate_kbps=kbps,
            max_bitrate_kbps=ceiling,
            fps=self._current.fps,
            vbv_kbit=h264_vbv_kbit(kbps, link, s.h264.refresh),
        )

    def state(self) -> VideoState:
        """A consistent snapshot of what is in effect."""
        with self._lock:
            known = sorted(self._known_resolutions(), key=lambda r: (r.width * r.height, r.width))
            size = self._stream_size if self.h264 else None
            adapt = bool(self._settings.adapt_to_link)
            return VideoState(
                params=self._current if size is None else replace(self._current, resolution=size),
                source=self._source,
                budget_kbps=self._budget_kbps(),
                level=self._budget.level,
                resolutions=tuple(dict.fromkeys(known)),
                adapt=adapt,
                link_budget_kbps=self._link.budget_kbps if adapt else 0.0,
                link_state=self._link.state if adapt else "off",
                link_queue_delay_s=self._decision.queue_delay_s if self._decision else float("nan"),
            )

    # -- what is asked for ---------------------------------------------------------------------------------
    def check(self, settings: VideoSettings, changed: Collection[str]) -> str | None:
        """The reason ``settings`` cannot be asked for (None = fine), when ``changed`` touches the request:
        fps and compression ranges, the resolution against the camera's own list once known."""
        if H264_FIELDS.intersection(changed) or "codec" in changed:
            reason = check_h264(settings)
            if reason:
                return reason
        if not VIDEO_FIELDS.intersection(changed):
            return None
        try:
            vp = self._request(settings)
            vp.validate(self._resolutions or ())  # the camera's own list once known (never assumed)
        except InvalidArgument as err:
            return str(err)
        return None

    def apply(self, settings: VideoSettings, changed: Collection[str], source: str = "parameter") -> VideoParams:
        """Take checked ``settings`` (``changed`` = the names that were set, even to the same value: a set
        restarts the ladder from the request); ``source`` becomes the cause of the parameters in effect, announced,
        when the video fields were touched (the encoder's fields are announced too, and in h264 mode a link setting
        that moves the budget in force: the cause left as it was)."""
        now = self._clock()
        names = set(changed)
        video = bool(VIDEO_FIELDS & names)
        with self._lock:
            was_h264 = self.h264
            self._settings = settings
            if LINK_FIELDS & names or self.h264 != was_h264:
                self._codec_switched(now)
            if video:
                requested = self._request(settings)
                if names & {"budget_max_compression", "budget_min_fps"}:
                    self._budget = BandwidthController(
                        requested, self._effective_budget(), self._known_resolutions(), settings.budget_config()
                    )
                else:
                    self._budget.configure(requested=requested, budget_kbps=self._effective_budget(), now=now)
                self._screen.stepped_up = False  # the user's change, not a step the link must prove
                self._current = self._budget.current
                self._source = source
            moved = self._h264_budget_moved()  # (adaptation switched off: the link's budget is gone)
        if video:
            self.mjpeg.configure(self._share_request(settings), self._resolutions, int(settings.budget_max_compression))
        if video or H264_FIELDS & names or moved:  # (the encoder's settings are announced with the rest)
            self._announce()
        return self._current

    def learn_resolutions(self, listed: Collection[Resolution]) -> None:
        """The camera's own resolution list (once; later calls are ignored): resolution '' becomes its largest,
        the ladder steps through its sizes; announced (the cause of the parameters stays as it was)."""
        if not listed:
            return
        with self._lock:
            if self._resolutions is not None:
                return
            self._resolutions = tuple(listed)
            self._budget.configure(
                requested=self._request(self._settings), resolutions=self._resolutions, now=self._clock()
            )
            self._current = self._budget.current
        s = self._settings
        self.mjpeg.configure(self._share_request(s), self._resolutions, int(s.budget_max_compression))
        self._announce()

    # -- what happens --------------------------------------------------------------------------------------
    def on_frame(self, now: float) -> BudgetStep | None:
        """Hot path (every frame): at most every :data:`BUDGET_PERIOD_S` while a budget applies, measure and
        switch settings when the budget says so (announced as ``bandwidth_budget``)."""
        budget = self._budget
        if (budget.budget_kbps <= 0 and budget.level == 0) or now - self._budget_check < BUDGET_PERIOD_S:
            return None
        self._budget_check = now
        with self._lock:
            budget = self._budget
            if budget.budget_kbps <= 0 and budget.level == 0:
                return None
            rate = self._meter.rate(now)
            before = budget.level
            # a still sent meanwhile takes its share of the budget (at most STILL_SHARE of it) for one meter window
            reserve = min(self._extra.kbps(now), STILL_SHARE * budget.budget_kbps)
            choice = budget.update(now, rate.kbps, rate.fps, rate.bytes_per_frame, rate.frames, reserve)
            if choice is None:
                return None
            step = BudgetStep(before, budget.level, choice, budget.budget_kbps, rate)
            self._screen.stepped_up = step.after < before
            self._current = choice
            self._source = "bandwidth_budget"
        self._announce()
        return step

    def on_still(self, now: float, nbytes: int) -> None:
        """A still of ``nbytes`` went out on the link (``still/compressed``). MJPEG: for one meter window its rate
        (at most :data:`STILL_SHARE` of the budget) is reserved out of the budget; the ladder jumps under what is
        left, then climbs back (the still's size never enters the frame-size learning). h264: the encoder leaves it
        most of the link until :meth:`still_crossed`, and reports covering that time are not judged
        (:class:`~.still.StillWindow`)."""
        self._extra.add(now, nbytes)
        if self.h264:
            link = self._link.budget_kbps if self._settings.adapt_to_link else 0.0
            ref = link if link > 0 else float(self._settings.h264.bitrate_kbps)
            self._still.start(now, ref)

    def still_crossed(self, now: float) -> None:
        self._still.end(now)  # every reader acknowledged the still (or it will not arrive): the full target is back

    def on_h264_frame(self, now: float, nbytes: int) -> None:
        """An H.264 access unit of ``nbytes`` was sent (h264 mode: what consumers' reports are judged against)."""
        self._h264_meter.add(now, nbytes)

    def host_clock_stepped(self) -> None:
        """This host's wall clock stepped (:class:`~.wall_clock.WallClockSteps`): the frames' stamps jumped with it,
        so the consumers' delays did, against a smallest delay from before the step: their reports are not judged
        until that has left their windows (a step back read as a queue as long as the step, and cut the budget)."""
        self._screen.clock_step_at = self._clock()

    def feedback(self, report: FeedbackReport, subscribed: Callable[[str], bool]) -> LinkJudgement | None:
        """A consumer's report (``subscribed(consumer)``: whether its image subscription has been discovered).
        Returns the judgement, or None when adaptation is off or the report says nothing about the link yet."""
        if not self._settings.adapt_to_link:
            return None
        now = self._clock()
        meter = self._h264_meter if self.h264 else self._meter
        sent = meter.rate(now)
        still = self._still.covers if self.h264 else None
        judged = self._screen.judgeable(report, now, sent, subscribed, meter.window_s, self._budget.changed_at, still)
        with self._lock:
            if judged is None:  # not evidence about the link, but the link is alive
                self._link.heard(now)
                return None
            level = self._budget.level
            grow_from = 0.0
            if self.h264:  # room to grow to the ceiling (back to the start bitrate when that is the ceiling)
                start, top = float(self._settings.h264.bitrate_kbps), float(self._settings.h264.max_bitrate_kbps)
                step_up = start
                if top > start:  # the budget at which the encoder reaches the ceiling; a clear link starts one
                    step_up, grow_from = top / H264_BUDGET_FRACTION, start
            else:
                step_up = self._budget.predict_kbps(level - 1, sent.bytes_per_frame) if level > 0 else 0.0
            decision = self._link.report(now, judged, sent.fps, sent.kbps, step_up, grow_from)
            self._decision = decision
            announce = self._apply_link_budget(now)
        if announce:
            self._announce()
        return LinkJudgement(decision, judged, sent, level)

    def tick(self) -> None:
        """Periodically (1 Hz): the link adapter holds its budget through a silence and lets go after
        ``link_release``; the budget in force follows."""
        now = self._clock()
        with self._lock:
            if not self._settings.adapt_to_link:
                return
            before = self._link.budget_kbps
            self._link.tick(now)
            if self._link.budget_kbps == before:
                return
            # held at what was sent through a silence, or released after a long one: back to the hand budget
            announce = self._apply_link_budget(now)
        if announce:
            self._announce()

    # -- internals -----------------------------------------------------------------------------------------
    def _codec_switched(self, now: float) -> None:
        """A new codec in effect (or new link settings): what was learned of the link was in another unit (JPEG
        bytes vs H.264 bytes); the MJPEG ladder's budget follows. Call with the lock held."""
        self._link = LinkAdapter(_adapter_config(self._settings, self.h264))
        self._budget.set_budget(self._effective_budget(), now)

    def _known_resolutions(self) -> tuple[Resolution, ...]:
        return self._resolutions if self._resolutions else AXIS214_PAL_RESOLUTIONS

    def _request(self, settings: VideoSettings) -> VideoParams:
        """The request for ``settings`` (:func:`~.video_request.camera_request`; not validated)."""
        h264 = settings.codec == "h264" and self._h264_possible
        return camera_request(settings, self._resolutions, h264, self._camera)

    def _share_request(self, settings: VideoSettings) -> VideoParams:
        """The MJPEG stream's request in h264 mode (:func:`~.video_request.share_request`)."""
        return share_request(settings, self._resolutions, self._camera)

    def _effective_budget(self) -> float:
        """The budget for the MJPEG ladder (0 = none; in h264 mode the encoder takes it); call with the lock held."""
        return 0.0 if self.h264 else self._budget_kbps()

    def _budget_kbps(self) -> float:
        """The tighter of the hand-set budget and the link's (0 = none); call with the lock held."""
        link = self._link.budget_kbps if self._settings.adapt_to_link else 0.0
        budgets = [b for b in (float(self._settings.max_bitrate_kbps), link) if b > 0]
        return min(budgets) if budgets else 0.0

    def _h264_budget_moved(self) -> bool:
        """h264 mode: whether the budget in force moved materially since the last announcement (by
        :data:`BUDGET_ANNOUNCE_SLACK` of it, or came or went); in MJPEG mode the ladder's steps announce it. Call
        with the lock held."""
        if not self.h264:
            return False
        kbps, last = self._budget_kbps(), self._announced_kbps
        if kbps == last:
            return False
        return kbps <= 0 or last <= 0 or abs(kbps - last) >= BUDGET_ANNOUNCE_SLACK * last

    def _apply_link_budget(self, now: float) -> bool:
        """After the link adapter has judged (a consumer's report, a tick): the budget in force follows its budget;
        in h264 mode a material move (:meth:`_h264_budget_moved`) becomes the cause of the parameters
        (``bandwidth_budget``). Returns whether to announce (:meth:`_announce`, once the lock is released). Call with
        the lock held."""
        self._budget.set_budget(self._effective_budget(), now)
        announce = self._h264_budget_moved()
        if announce:
            self._source = "bandwidth_budget"
        return announce

    def _announce(self) -> None:
        """Tell the listener; serialised, so the last announcement describes the latest state."""
        with self._lock:
            self._announced_kbps = self._budget_kbps()
        if self._on_change is None:
            return
        with self._notify_lock:
            self._on_change()


def _adapter_config(settings: VideoSettings, h264: bool) -> AdapterConfig:
    """The link adapter's tuning for the codec in effect (H.264 is judged by bytes, with a lossy link's repair
    delays allowed for: :func:`~.adapter_config.h264_adapter_config`)."""
    release = float(settings.link_release)
    return h264_adapter_config(release) if h264 else AdapterConfig(release_s=release)
