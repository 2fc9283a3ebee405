"""Which consumer reports say something about the link (ROS-free): the video controller judges only those.

A report on ``video/feedback`` covers the consumer's last window (2 s). Some windows hold what the stream node did
itself, not the link: a switch of settings (the reconnect's gap, the old settings' frames), a still on demand
crossing the link (its queue is ours), a stream that only just (re)started, a consumer whose subscription this node
has not discovered yet, and a step of this host's wall clock (the frames' stamps jumped with it, against the
consumer's smallest delay from before the step). :class:`ReportScreen` keeps what decides that between reports; the
one exception it makes the other way is a step up of the ladder that stopped the video: judged at once as "nothing
arrives".
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from axis_ptz_ros2.streaming.feedback import FeedbackReport
from axis_ptz_ros2.streaming.meter import Rate
from axis_ptz_ros2.streaming.receive_meter import BASE_WINDOW_S

#: s: a consumer's report is judged only once its window starts this long after a switch of settings
FEEDBACK_SETTLE_S = 0.5
#: s: ... except when a step up has streamed this long and the consumer has received nothing for as long (it
#: swamps the link: waiting for a clean window would lose every frame for window + settle, 2.5 s, on each failed
#: step up)
SWAMPED_AFTER_STEP_UP_S = 1.0


@dataclass(slots=True)
class ReportScreen:
    """What decides whether a report is judged, between reports (the controller's lock guards it)."""

    stepped_up: bool = False  #: the ladder's last switch was to better settings (one the link must prove)
    clock_step_at: float | None = None  #: when this host's wall clock last stepped (monotonic s)

    def judgeable(
        self,
        r: FeedbackReport,
        now: float,
        sent: Rate,
        subscribed: Callable[[str], bool],
        meter_window_s: float,
        changed_at: float | None,
        still_covers: Callable[[float, float], bool] | None,
    ) -> FeedbackReport | None:
        """The report to judge, or None when it says nothing about the link yet. ``sent``: what the stream node
        measured sending (its meter of ``meter_window_s`` restarts with each connection: its span is how long the
        new settings have been streaming); ``changed_at``: the ladder's last switch; ``still_covers(now, window)``:
        whether a still crossed the link in that window (h264 mode; None otherwise)."""
        if r.frames == 0 and not subscribed(r.consumer):
            # "nothing received" from a consumer whose subscription has not been discovered here: the writer
            # is not sending to it yet (discovery over a lossy link can take long), which says nothing of the link
            return None
        if (
            self.stepped_up
            and sent.frames >= 2
            and sent.span_s >= SWAMPED_AFTER_STEP_UP_S
            and r.gap_s >= SWAMPED_AFTER_STEP_UP_S
        ):
            # a step up that stopped the video: judge it now as "nothing arrives" (the window's frames are
            # mostly the old settings')
            return FeedbackReport(r.consumer, 0, 0.0, 0.0, 0.0, r.delay_min_s, r.gap_s, r.window_s)
        if changed_at is not None and now - changed_at < r.window_s + FEEDBACK_SETTLE_S:
            return None  # the report's window still holds the switch (the reconnect's gap, the old settings)
        if still_covers is not None and still_covers(now, r.window_s + FEEDBACK_SETTLE_S):
            return None  # the report's window holds a still crossing the link: its queue is ours
        if r.frames == 0 and sent.span_s < 0.75 * meter_window_s:
            return None  # nothing received, but the stream has only just (re)started: not a swamped link
        stepped = self.clock_step_at
        if stepped is not None and now - stepped < BASE_WINDOW_S + r.window_s + FEEDBACK_SETTLE_S:
            return None  # the delays mix stamps from both sides of a step of this host's clock
        return r
