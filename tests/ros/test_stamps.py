"""``nodes.common.stamp_s``: a message stamp in seconds through rclpy's ``Time.from_msg``, the inverse of
``stamp_from_ns`` (the stream node stamps frames with the wall clock; the link monitor and the console compare
those seconds with ``time.time()``)."""

from __future__ import annotations

import time

import pytest

pytest.importorskip("rclpy")

from builtin_interfaces.msg import Time  # noqa: E402

from axis_ptz_ros2.nodes.common import stamp_from_ns, stamp_s  # noqa: E402

pytestmark = pytest.mark.ros


@pytest.mark.parametrize("ns", [1, 999_999_999, 1_000_000_000, 1_700_000_000_123_456_789, 2**31 * 10**9 - 1])
def test_stamp_s_is_the_stamps_nanoseconds_in_seconds(ns: int) -> None:
    s = stamp_s(stamp_from_ns(ns))
    assert s == ns / 1_000_000_000  # exact division of the integer nanoseconds
    t = stamp_from_ns(ns)
    assert s == pytest.approx(t.sec + t.nanosec * 1e-9, rel=0, abs=1e-6)  # the hand-written sum it replaces


def test_a_wall_clock_stamp_reads_back_as_now() -> None:
    assert stamp_s(stamp_from_ns(time.time_ns())) == pytest.approx(time.time(), abs=0.5)


def test_no_stamp_and_a_stamp_before_1970_are_not_positive() -> None:
    assert stamp_s(Time()) == 0.0
    assert stamp_s(Time(sec=-5, nanosec=10)) == 0.0  # rclpy's Time refuses it; the callers skip stamps <= 0
