"""ROS tier fixtures: nodes and probes over real DDS (Fast DDS, loopback only), one context per test."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

rclpy = pytest.importorskip("rclpy")  # with AXIS_REQUIRE_ALL_TIERS=1 a skip here fails the run

from axis_ptz_ros2.nodes.harness import RosHarness  # noqa: E402

pytestmark = pytest.mark.ros


@pytest.fixture
def ros() -> Iterator[RosHarness]:
    """A fresh ROS context per test."""
    h = RosHarness()
    try:
        yield h
    finally:
        h.close()
