"""Start points and who reports (ROS-free): :meth:`StartPoints.long_wave` says whether every H.264 viewer has
reported on ``video/feedback`` long enough, without a gap, and none lost anything lately, for the encoder's wave to
be longer than a second."""

from __future__ import annotations

import pytest

from axis_ptz_ros2.media.h264_settings import H264Settings
from axis_ptz_ros2.streaming.h264 import H264Stage
from axis_ptz_ros2.streaming.start_points import (
    CALM_S,
    CLEAN_FOR_S,
    MAX_REPORTERS,
    REPORT_GAP_S,
    REPORTING_FOR_S,
    StartPoints,
)
from axis_ptz_ros2.streaming.status import wave_line

pytestmark = pytest.mark.unit

MONITOR = "/operator/link_monitor"
RVIZ = "/rviz2"


class Clock:
    def __init__(self) -> None:
        self.t = 50.0

    def __call__(self) -> float:
        return self.t


def _starts() -> tuple[StartPoints, Clock]:
    clock = Clock()
    stage = H264Stage(H264Settings, lambda _f: None, clock=clock)
    return StartPoints(stage, clock), clock


def _report_for(starts: StartPoints, clock: Clock, consumer: str, seconds: float, period: float = 0.5) -> None:
    for _ in range(round(seconds / period)):
        clock.t += period
        starts.report(consumer, 12, 0)


def test_every_viewer_reporting_long_enough_without_a_gap_lets_the_wave_be_long() -> None:
    starts, clock = _starts()
    assert not starts.long_wave(clock.t)  # no viewer: nothing to say
    starts.count(1, lambda: frozenset({MONITOR}))
    starts.report(MONITOR, 12, 0)
    assert not starts.long_wave(clock.t)  # its first report does not yet change the wave
    _report_for(starts, clock, MONITOR, REPORTING_FOR_S - 1.0)
    assert not starts.long_wave(clock.t)
    _report_for(starts, clock, MONITOR, 1.0)
    assert starts.long_wave(clock.t)


def test_a_reported_loss_ends_the_long_wave_until_the_viewers_see_none_for_a_while() -> None:
    """Each loss costs an IDR squeezed into the link's VBV, whose blur a long wave would keep for seconds."""
    starts, clock = _starts()
    starts.count(1, lambda: frozenset({MONITOR}))
    _report_for(starts, clock, MONITOR, REPORTING_FOR_S + 0.5)
    assert starts.long_wave(clock.t)
    clock.t += 0.5
    starts.report(MONITOR, 12, 3)  # three access units it could not show
    assert not starts.long_wave(clock.t)
    _report_for(starts, clock, MONITOR, CLEAN_FOR_S - 1.0)
    assert not starts.long_wave(clock.t)
    _report_for(starts, clock, MONITOR, 1.5)
    assert starts.long_wave(clock.t)
    # any viewer's loss counts, whoever it is
    starts.report("/operator/web_console", 12, 1)
    assert not starts.long_wave(clock.t)


def test_a_loss_in_a_congestion_does_not_end_the_long_wave_but_one_after_it_does() -> None:
    """A new wave re-opens x264 cold: not in a congestion, where that kept the link congested for seconds."""
    starts, clock = _starts()
    starts.count(1, lambda: frozenset({MONITOR}))
    _report_for(starts, clock, MONITOR, REPORTING_FOR_S + 0.5)
    starts.congested(clock.t)  # the link adapter's judgement of a report
    starts.report(MONITOR, 12, 5)
    assert starts.long_wave(clock.t)
    _report_for(starts, clock, MONITOR, CALM_S - 1.0)
    starts.report(MONITOR, 12, 2)  # the congestion's losses still in its window
    assert starts.long_wave(clock.t)
    _report_for(starts, clock, MONITOR, 1.5)
    starts.report(MONITOR, 12, 1)  # a loss once the congestion has passed: random loss
    assert not starts.long_wave(clock.t)


def test_a_silent_viewer_or_a_reporter_gone_quiet_ends_it() -> None:
    starts, clock = _starts()
    starts.count(1, lambda: frozenset({MONITOR}))
    _report_for(starts, clock, MONITOR, REPORTING_FOR_S + 0.5)
    assert starts.long_wave(clock.t)
    starts.count(2, lambda: frozenset({MONITOR, RVIZ}))  # rviz joins: it does not report
    assert not starts.long_wave(clock.t)
    starts.count(1, lambda: frozenset({MONITOR}))  # ... and leaves: the monitor's streak went on meanwhile
    _report_for(starts, clock, MONITOR, 0.5)
    assert starts.long_wave(clock.t)
    clock.t += REPORT_GAP_S + 0.1  # the monitor falls silent
    assert not starts.long_wave(clock.t)
    starts.report(MONITOR, 12, 0)  # back: a new streak, which must last again
    assert not starts.long_wave(clock.t)
    _report_for(starts, clock, MONITOR, REPORTING_FOR_S + 0.5)
    assert starts.long_wave(clock.t)


def test_a_reporter_that_leaves_and_comes_back_starts_a_new_streak() -> None:
    starts, clock = _starts()
    starts.count(1, lambda: frozenset({MONITOR}))
    _report_for(starts, clock, MONITOR, REPORTING_FOR_S + 0.5)
    starts.count(0, frozenset)
    assert not starts.long_wave(clock.t)
    starts.count(1, lambda: frozenset({MONITOR}))
    starts.report(MONITOR, 12, 0)
    assert not starts.long_wave(clock.t)


def test_a_viewer_the_graph_names_late_is_learnt_at_the_next_count() -> None:
    """Across hosts the publisher matches a subscription before the graph knows its node: the first count lists
    an unknown name (or none); a later count with the same number of subscribers learns the real one."""
    starts, clock = _starts()
    starts.count(1, lambda: frozenset({"/_NODE_NAMESPACE_UNKNOWN_/_NODE_NAME_UNKNOWN_"}))
    _report_for(starts, clock, MONITOR, REPORTING_FOR_S + 0.5)
    assert not starts.long_wave(clock.t)
    starts.count(1, lambda: frozenset({MONITOR}))  # the 1 Hz count, the same number
    assert starts.long_wave(clock.t)  # its streak was kept meanwhile


def test_a_report_from_a_node_that_does_not_subscribe_counts_for_nothing() -> None:
    starts, clock = _starts()
    starts.count(1, lambda: frozenset({RVIZ}))
    _report_for(starts, clock, MONITOR, REPORTING_FOR_S + 1.0)
    assert not starts.long_wave(clock.t)


def test_consumers_that_come_and_go_are_forgotten_but_not_one_reporting_now() -> None:
    starts, clock = _starts()
    starts.count(1, lambda: frozenset({MONITOR}))
    _report_for(starts, clock, MONITOR, REPORTING_FOR_S + 0.5)
    for k in range(3 * MAX_REPORTERS):  # short-lived consumers, one report each
        clock.t += 0.02
        starts.report(f"/viewer_{k}", 12, 0)
        if k % 25 == 0:
            starts.report(MONITOR, 12, 0)
    assert len(starts._reporting) <= MAX_REPORTERS + 1  # noqa: SLF001 - the bound is the point
    assert starts.long_wave(clock.t)  # the monitor's streak survived


def test_the_wave_line_says_how_long_and_why() -> None:
    on = wave_line(H264Settings(reported_wave=100, fps=25, long_wave=True))
    assert "100 frames" in on
    assert "reports its losses" in on
    off = wave_line(H264Settings(reported_wave=100, fps=25))
    assert "one second" in off
    assert "does not report" in off
