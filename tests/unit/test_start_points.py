"""Start points (ROS-free): who the H.264 viewers are, as the graph names them."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from axis_ptz_ros2.media.h264_settings import H264Settings
from axis_ptz_ros2.streaming.h264 import H264Stage
from axis_ptz_ros2.streaming.start_points import StartPoints

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
