"""A step of the operator's wall clock (NTP on the laptop) is no delay on the link (``axis_link_monitor``).

The monitor measures each frame's delay from the stream node's stamp (the robot's clock) to its arrival (its own
clock); the two clocks' offset cancels against the smallest delay of the last 10 s. A step of the monitor's clock
changed every delay after it at once: +0.5 s read as a 0.5 s queue for 10 s, and the stream node cut the video.
Over real DDS, the stream node against the simulated camera; the monitor's wall clock is scripted (its offset from
the true time steps by +0.5 s mid-run), the robot's is the real one.
"""

from __future__ import annotations

import time

import pytest

pytest.importorskip("rclpy")

from axis_ptz_interfaces.msg import LinkFeedback  # noqa: E402
from axis_ptz_ros2.nodes.common import FEEDBACK_QOS  # noqa: E402
from axis_ptz_ros2.nodes.link_monitor import LinkMonitorNode  # noqa: E402
from axis_ptz_ros2.sim import SimulatedCamera  # noqa: E402
from axis_ptz_ros2.streaming.wall_clock import WallClockSteps  # noqa: E402
from tests.support.harness import RosHarness  # noqa: E402
from tests.support.stream_node import make_stream_node  # noqa: E402

pytestmark = pytest.mark.ros

STEP_S = 0.5


def test_a_step_of_the_monitors_clock_reads_as_no_queue(ros: RosHarness, camera: SimulatedCamera) -> None:
    make_stream_node(ros, camera, resolution="352x288", fps=10, adapt_to_link=False)
    monitor = ros.add(LinkMonitorNode(context=ros.context))
    offset = [0.0]  # the monitor's wall clock against the true time
    monitor.feedback.wall = lambda: time.time() + offset[0]
    monitor.feedback.host_clock = WallClockSteps(wall_ns=lambda: time.time_ns() + round(offset[0] * 1e9))
    probe = ros.probe()
    reports: list[LinkFeedback] = []
    probe.create_subscription(LinkFeedback, "video/feedback", reports.append, FEEDBACK_QOS)
    ros.wait_for(lambda: sum(r.frames >= 15 for r in list(reports)) >= 3, 20.0)  # full windows before the step

    offset[0] = STEP_S
    n = len(reports)
    ros.wait_for(lambda: sum(r.frames >= 15 for r in list(reports)[n:]) >= 6, 15.0)  # 3 s of reports after it
    after = [r for r in list(reports)[n:] if r.frames >= 15]
    queues = [r.delay_p95_s - r.delay_min_s for r in after]
    # a queue on loopback is milliseconds; the step would have read as 0.5 s in every one of these reports
    assert max(queues) < STEP_S / 2, queues
    assert monitor.feedback.host_clock.steps == 1
