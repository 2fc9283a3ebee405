"""Whether the encoder's intra-refresh wave may be long (ROS-free): :meth:`LongWave.allowed` says so while every
H.264 viewer has reported on ``video/feedback`` long enough, without a gap, and none lost anything lately outside a
congestion."""

from __future__ import annotations

import pytest

from axis_ptz_ros2.media.h264_settings import H264Settings
from axis_ptz_ros2.streaming.long_wave import (
    CALM_S,
    CLEAN_FOR_S,
    MAX_REPORTERS,
    REPORT_GAP_S,
    REPORTING_FOR_S,
    LongWave,
)
from axis_ptz_ros2.streaming.status import wave_line

pytestmark = pytest.mark.unit

MONITOR = "/operator/link_monitor"
RVIZ = "/rviz2"


class Clock:
    t = 50.0


def _report_for(wave: LongWave, clock: Clock, consumer: str, seconds: float, period: float = 0.5) -> None:
    for _ in range(round(seconds / period)):
        clock.t += period
        wave.report(consumer, 0, clock.t)


def _reporting(viewers: frozenset[str] = frozenset({MONITOR})) -> tuple[LongWave, Clock]:
    """The monitor alone watching, reporting long enough: the wave may be long."""
    wave, clock = LongWave(), Clock()
    wave.set_viewers(viewers)
    _report_for(wave, clock, MONITOR, REPORTING_FOR_S + 0.5)
    return wave, clock


def test_every_viewer_reporting_long_enough_without_a_gap_lets_the_wave_be_long() -> None:
    wave, clock = LongWave(), Clock()
    assert not wave.allowed(clock.t)  # no viewer: nothing to say
    wave.set_viewers(frozenset({MONITOR}))
    wave.report(MONITOR, 0, clock.t)
    assert not wave.allowed(clock.t)  # its first report does not yet change the wave
    _report_for(wave, clock, MONITOR, REPORTING_FOR_S - 1.0)
    assert not wave.allowed(clock.t)
    _report_for(wave, clock, MONITOR, 1.5)
    assert wave.allowed(clock.t)


def test_a_reported_loss_ends_the_long_wave_until_the_viewers_see_none_for_a_while() -> None:
    """Each loss costs an IDR squeezed into the link's VBV, whose blur a long wave would keep for seconds."""
    wave, clock = _reporting()
    clock.t += 0.5
    wave.report(MONITOR, 3, clock.t)  # three access units it could not show
    assert not wave.allowed(clock.t)
    _report_for(wave, clock, MONITOR, CLEAN_FOR_S - 1.0)
    assert not wave.allowed(clock.t)
    _report_for(wave, clock, MONITOR, 1.5)
    assert wave.allowed(clock.t)
    wave.report("/operator/web_console", 1, clock.t)  # any viewer's loss counts, whoever it is
    assert not wave.allowed(clock.t)


def test_a_loss_in_a_congestion_does_not_end_the_long_wave_but_one_after_it_does() -> None:
    """A new wave re-opens x264 cold: not in a congestion, where that kept the link congested for seconds."""
    wave, clock = _reporting()
    wave.congested(clock.t)  # the link adapter's judgement of a report
    wave.report(MONITOR, 5, clock.t)
    assert wave.allowed(clock.t)
    _report_for(wave, clock, MONITOR, CALM_S - 1.0)
    wave.report(MONITOR, 2, clock.t)  # the congestion's losses still in its window
    assert wave.allowed(clock.t)
    _report_for(wave, clock, MONITOR, 1.5)
    wave.report(MONITOR, 1, clock.t)  # a loss once the congestion has passed: random loss
    assert not wave.allowed(clock.t)


def test_a_silent_viewer_or_a_reporter_gone_quiet_ends_it() -> None:
    wave, clock = _reporting()
    wave.set_viewers(frozenset({MONITOR, RVIZ}))  # rviz joins: it does not report
    assert not wave.allowed(clock.t)
    wave.set_viewers(frozenset({MONITOR}))  # ... and leaves: the monitor's streak went on meanwhile
    _report_for(wave, clock, MONITOR, 0.5)
    assert wave.allowed(clock.t)
    clock.t += REPORT_GAP_S + 0.1  # the monitor falls silent
    assert not wave.allowed(clock.t)
    wave.report(MONITOR, 0, clock.t)  # back: a new streak, which must last again
    assert not wave.allowed(clock.t)
    _report_for(wave, clock, MONITOR, REPORTING_FOR_S + 0.5)
    assert wave.allowed(clock.t)


def test_when_nobody_watches_every_streak_ends() -> None:
    wave, clock = _reporting()
    wave.set_viewers(frozenset())
    assert not wave.allowed(clock.t)
    wave.set_viewers(frozenset({MONITOR}))  # the monitor back at once
    wave.report(MONITOR, 0, clock.t)
    assert not wave.allowed(clock.t)


def test_a_report_from_a_node_that_does_not_subscribe_counts_for_nothing() -> None:
    wave, clock = _reporting(frozenset({RVIZ}))
    _report_for(wave, clock, MONITOR, 1.0)
    assert not wave.allowed(clock.t)


def test_consumers_that_come_and_go_are_forgotten_but_not_one_reporting_now() -> None:
    wave, clock = _reporting()
    for k in range(3 * MAX_REPORTERS):  # short-lived consumers, one report each
        clock.t += 0.02
        wave.report(f"/viewer_{k}", 0, clock.t)
        if k % 25 == 0:
            wave.report(MONITOR, 0, clock.t)
    assert wave.reporters <= MAX_REPORTERS + 1
    assert wave.allowed(clock.t)  # the monitor's streak survived


def test_the_wave_line_says_how_long_and_why() -> None:
    on = wave_line(H264Settings(reported_wave=100, fps=25, long_wave=True))
    assert "100 frames" in on
    assert "reports its losses" in on
    off = wave_line(H264Settings(reported_wave=100, fps=25))
    assert "one second" in off
    assert "does not report" in off
