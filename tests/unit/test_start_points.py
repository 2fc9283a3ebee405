"""Start points (ROS-free): who the H.264 viewers are, as the graph names them."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from axis_ptz_ros2.media.h264_settings import H264Settings
from axis_ptz_ros2.streaming.h264 import NEW_SUBSCRIBER_IDR_AGAIN_S, H264Stage
from axis_ptz_ros2.streaming.start_points import START_IDR_REPEATS_S, StartPoints

pytestmark = pytest.mark.unit

MONITOR = "/operator/link_monitor"
UNKNOWN = "/_NODE_NAMESPACE_UNKNOWN_/_NODE_NAME_UNKNOWN_"


def test_a_viewer_the_graph_names_late_is_learnt_at_the_next_count() -> None:
    """Across hosts the publisher matches a subscription before the graph knows its node: the first count lists
    an unknown name (or none); a later count with the same number of subscribers learns the real one (asked only
    when the number changed, it stayed unknown: the long wave never came in the two-host bench)."""
    stage = H264Stage(H264Settings, lambda _f: None)
    starts = StartPoints(stage)
    asked: list[int] = []

    def names(found: frozenset[str]) -> Callable[[], frozenset[str]]:
        def viewers() -> frozenset[str]:
            asked.append(1)
            return found

        return viewers

    starts.count(1, names(frozenset({UNKNOWN})))
    assert starts.viewers == {UNKNOWN}
    starts.count(1, names(frozenset({MONITOR})))  # the 1 Hz count, the same number
    assert starts.viewers == {MONITOR}
    starts.count(0, names(frozenset()))
    assert starts.viewers == frozenset()
    starts.count(0, names(frozenset({MONITOR})))  # nobody: not asked
    assert len(asked) == 3


def on_a_fake_clock() -> tuple[list[float], H264Stage, StartPoints]:
    """([now], stage, start points), both reading ``now[0]`` as their clock."""
    now = [0.0]
    stage = H264Stage(H264Settings, lambda _f: None, clock=lambda: now[0])
    return now, stage, StartPoints(stage, clock=lambda: now[0])


def start_point_times(seconds: float, tick: float = 0.04) -> list[float]:
    """When a plain viewer (one that never reports) is sent IDRs after it appeared at 0, by the stage and the start
    points together, with an access unit every ``tick`` s (the RTSP path's ``idr_wanted`` / ``idr_sent``)."""
    now, stage, starts = on_a_fake_clock()
    stage.set_active(True)
    stage.idr_sent()  # the stream's own first IDR, long before the viewer
    now[0] = 10.0
    t0 = now[0]
    starts.count(1, lambda: frozenset({"/plain_viewer"}))
    sent: list[float] = []
    while now[0] < t0 + seconds:
        if starts.repeat_due(now[0]):
            stage.request_idr()
        if stage.idr_wanted:
            stage.idr_sent()
            sent.append(round(now[0] - t0, 3))
        now[0] += tick
    return sent


def test_a_plain_viewer_gets_its_start_points_and_no_more() -> None:
    """A viewer that never reports gets the stage's IDRs (at once, ``NEW_SUBSCRIBER_IDR_AGAIN_S`` later) and one
    at each of :data:`START_IDR_REPEATS_S`, and none after the last (a plain viewer does not cost IDRs for good)."""
    sent = start_point_times(START_IDR_REPEATS_S[-1] + 3.0)
    expected = [0.0, NEW_SUBSCRIBER_IDR_AGAIN_S, *START_IDR_REPEATS_S]
    assert len(sent) == len(expected), sent
    assert all(abs(a - b) <= 0.05 for a, b in zip(sent, expected, strict=True)), sent


def test_start_points_stop_once_the_viewer_reports_pictures() -> None:
    """A viewer that reports pictures without errors on ``video/feedback`` has had its start point: no more IDRs."""
    now, _stage, starts = on_a_fake_clock()
    starts.count(1, lambda: frozenset({MONITOR}))
    now[0] = START_IDR_REPEATS_S[0] + 0.05
    assert starts.repeat_due(now[0])  # the first repeat: not yet reported
    starts.report(MONITOR, frames=10, errors=0)
    now[0] = START_IDR_REPEATS_S[1] + 0.05
    assert not starts.repeat_due(now[0])
    assert not starts.pending
