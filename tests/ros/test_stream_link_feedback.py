"""The stream node's video/feedback wiring over real DDS: a consumer's congestion report reaches the controller,
whose link budget steps the stream down (video/params says why); with adapt_to_link false nothing changes."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from typing import Any

import pytest

pytest.importorskip("rclpy")

from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from sensor_msgs.msg import CompressedImage  # noqa: E402

from axis_ptz_interfaces.msg import LinkFeedback, VideoParams  # noqa: E402
from axis_ptz_ros2.nodes.common import FEEDBACK_QOS, LATCHED_QOS, STREAM_QOS  # noqa: E402
from axis_ptz_ros2.sim import SimulatedCamera  # noqa: E402
from tests.support.harness import RosHarness  # noqa: E402
from tests.support.sim import FAST_STREAM_PARAMS  # noqa: E402
from tests.support.stream_node import make_stream_node  # noqa: E402

pytestmark = pytest.mark.ros

FAST = FAST_STREAM_PARAMS


@pytest.fixture(scope="module")
def camera() -> Iterator[SimulatedCamera]:
    cam = SimulatedCamera(host="127.0.0.1", port=0).start()
    try:
        yield cam
    finally:
        cam.stop()


def _run(ros: RosHarness, camera: SimulatedCamera, adapt: bool, seconds: float) -> tuple[list[Any], dict[str, str]]:
    """Stream 704x576 @ 15 fps c0 to a consumer that reports a congested link; (video/params seen, diagnostics)."""
    make_stream_node(ros, camera, fps=15, resolution="704x576", compression=0, adapt_to_link=adapt)
    probe = ros.probe("link_consumer")
    lock = threading.Lock()
    params: list[Any] = []
    diag: dict[str, str] = {}
    frames: list[float] = []

    def on_params(msg: VideoParams) -> None:
        with lock:
            params.append(msg)

    def on_diag(msg: DiagnosticArray) -> None:
        for st in msg.status:
            if "MJPEG stream" in st.name:
                with lock:
                    diag.update({kv.key: kv.value for kv in st.values})

    probe.create_subscription(VideoParams, "video/params", on_params, LATCHED_QOS)
    probe.create_subscription(DiagnosticArray, "/diagnostics", on_diag, 10)
    probe.create_subscription(
        CompressedImage, "image_raw/compressed", lambda _m: frames.append(time.monotonic()), STREAM_QOS
    )
    pub = probe.create_publisher(LinkFeedback, "video/feedback", FEEDBACK_QOS)
    ros.wait_for(lambda: len(frames) >= 10, timeout=15)
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        # 5 of the 15 frames/s arrive, 0.9 s late on top of the link's own delay: a congested link
        msg = LinkFeedback(consumer=probe.get_fully_qualified_name(), window_s=1.0, frames=5, fps=5.0, kbps=300.0)
        msg.delay_p95_s, msg.delay_min_s, msg.gap_s = 1.0, 0.1, 0.05
        pub.publish(msg)
        time.sleep(0.25)  # a consumer's report every 0.25 s for ``seconds``: the controller judges over time
    with lock:
        return list(params), dict(diag)


def test_a_congested_consumer_steps_the_stream_down(ros: RosHarness, camera: SimulatedCamera) -> None:
    params, diag = _run(ros, camera, adapt=True, seconds=6.0)
    stepped = [m for m in params if m.source == "bandwidth_budget"]
    assert stepped, f"the link budget never switched settings: {[(m.source, m.compression) for m in params]}"
    last = stepped[-1]
    assert 0 < last.max_bitrate_kbps <= 300, "a budget under what the consumer received"
    assert (last.compression, last.fps, last.width) != (0, 15, 704)
    assert diag["link state"] != "off"


def test_without_adaptation_reports_change_nothing(ros: RosHarness, camera: SimulatedCamera) -> None:
    params, diag = _run(ros, camera, adapt=False, seconds=3.0)
    assert params, "video/params is latched"
    assert all(m.source != "bandwidth_budget" for m in params)
    assert (params[-1].compression, params[-1].fps, params[-1].width) == (0, 15, 704)
    assert diag["link state"] == "off"
    assert diag["max_bitrate_kbps"] == "0"
