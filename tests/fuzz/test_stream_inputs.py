"""The stream node's ROS inputs, generated (issue 25): parameter sets (what ``ros2 param set`` sends) of every
type and size, and ``video/feedback`` reports with NaN, ±inf, negative and huge figures — against the simulated
camera over real DDS. Properties: every refusal says why; the node keeps streaming; nothing reaches the camera that
is not valid (every ``video.cgi`` request the simulator logged has fps 1..30, compression 0..100 and a size the
camera lists); feedback of any shape never stops the stream.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from typing import Any
from urllib.parse import parse_qsl

import pytest

pytest.importorskip("rclpy")

from hypothesis import given  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from rcl_interfaces.srv import SetParameters  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from sensor_msgs.msg import CompressedImage  # noqa: E402

from axis_ptz_interfaces.msg import LinkFeedback  # noqa: E402
from axis_ptz_ros2.nodes.common import FEEDBACK_QOS, STREAM_QOS  # noqa: E402
from axis_ptz_ros2.nodes.stream_node import StreamNode  # noqa: E402
from axis_ptz_ros2.sim.camera import SimulatedCamera  # noqa: E402
from axis_ptz_ros2.sim.world import load_world  # noqa: E402
from tests.fuzz.ros_profile import ros_settings  # noqa: E402
from tests.support.harness import RosHarness  # noqa: E402

pytestmark = [pytest.mark.fuzz, pytest.mark.timeout(600)]

CAMERA_SIZES = {(704, 576), (704, 288), (352, 288), (176, 144)}  # the simulated 214's list

_value = st.one_of(
    st.integers(min_value=-(2**63), max_value=2**63 - 1),
    st.floats(allow_nan=True, allow_infinity=True),
    st.booleans(),
    st.text(max_size=20),
    st.sampled_from(["704x576", "352x288", "1x1", "99999x99999", "4294967648x288", "4CIF", "", "auto", "h264"]),
)
_names = st.sampled_from(["fps", "compression", "resolution", "max_bitrate_kbps", "adapt_to_link", "codec", "port"])


def _parameter_value(value: Any) -> Any:
    from rcl_interfaces.msg import ParameterValue

    return Parameter("x", value=value).get_parameter_value() if value is not None else ParameterValue()


@pytest.fixture(scope="module")
def rig() -> Iterator[tuple[RosHarness, SimulatedCamera, StreamNode, Any, list[float]]]:
    cam = SimulatedCamera(load_world(), port=0).start()
    ros = RosHarness()
    try:
        node = ros.add(StreamNode(context=ros.context, parameter_overrides=[Parameter("port", value=cam.port)]))
        probe = ros.probe("fuzz_stream_probe")
        arrivals: list[float] = []
        probe.create_subscription(
            CompressedImage, "image_raw/compressed", lambda _m: arrivals.append(time.monotonic()), STREAM_QOS
        )
        ros.wait_for(lambda: len(arrivals) > 3, 20.0)
        yield ros, cam, node, probe, arrivals
    finally:
        ros.close()
        cam.stop()


def _camera_saw_only_valid_requests(cam: SimulatedCamera) -> None:
    for entry in cam.request_counts.video_log:
        args = dict(parse_qsl(entry.query.split("?", 1)[-1], keep_blank_values=True))
        if "fps" in args:
            assert 1 <= int(args["fps"]) <= 30, entry.query
        if "compression" in args:
            assert 0 <= int(args["compression"]) <= 100, entry.query
        if "resolution" in args:
            w, h = (int(x) for x in args["resolution"].split("x"))
            assert (w, h) in CAMERA_SIZES, entry.query


def _still_streaming(ros: RosHarness, arrivals: list[float]) -> None:
    t = time.monotonic()
    ros.wait_for(lambda: arrivals and arrivals[-1] > t, 15.0)


@ros_settings
@given(st.lists(st.tuples(_names, _value), min_size=1, max_size=3))
def test_parameter_sets(rig: Any, changes: list[tuple[str, Any]]) -> None:
    ros, cam, node, probe, _arrivals = rig
    client = probe.__dict__.setdefault(
        "_set_params", probe.create_client(SetParameters, f"/{node.get_name()}/set_parameters")
    )
    request = SetParameters.Request()
    for name, value in changes:
        p = Parameter(name, value=value).to_parameter_msg()
        request.parameters.append(p)
    response = ros.call(client, request, timeout=10.0)
    assert response is not None
    for result in response.results:
        if not result.successful:
            assert result.reason.strip(), f"{changes} refused without a reason"
    _camera_saw_only_valid_requests(cam)


@ros_settings
@given(
    st.tuples(*[st.floats(allow_nan=True, allow_infinity=True, width=32)] * 8),
    st.integers(0, 2**32 - 1),
    st.text(max_size=30),
)
def test_feedback_reports(rig: Any, figures: tuple[float, ...], frames: int, consumer: str) -> None:
    ros, cam, _node, probe, _arrivals = rig
    pub = probe.__dict__.setdefault("_feedback", probe.create_publisher(LinkFeedback, "video/feedback", FEEDBACK_QOS))
    msg = LinkFeedback(consumer=consumer, frames=frames)
    (msg.window_s, msg.fps, msg.kbps, msg.delay_p95_s, msg.delay_min_s, msg.gap_s, msg.delay_p50_s,
     msg.delay_floor_s) = figures  # fmt: skip
    msg.header.frame_id = "image_raw/compressed"
    pub.publish(msg)
    _camera_saw_only_valid_requests(cam)


def test_after_all_that_the_node_streams_with_a_valid_request(rig: Any) -> None:
    ros, cam, node, probe, arrivals = rig
    client = probe.create_client(SetParameters, f"/{node.get_name()}/set_parameters")
    request = SetParameters.Request()
    # codec too: the fuzz may have left ``h264`` (a valid value), and then the MJPEG topic is the share's stream,
    # whose ladder may rightly ask for less than 352x288 (tests/ros/test_stream_crowded.py covers that case)
    settings = (
        ("codec", "mjpeg"),
        ("resolution", "352x288"),
        ("fps", 10),
        ("compression", 30),
        ("adapt_to_link", False),
    )
    for name, value in settings:
        request.parameters.append(Parameter(name, value=value).to_parameter_msg())
    response = ros.call(client, request, timeout=10.0)
    assert all(r.successful for r in response.results), [r.reason for r in response.results]
    _still_streaming(ros, arrivals)
    _camera_saw_only_valid_requests(cam)
    # the reader reconnects with the new request on its own thread: wait for the camera to have seen it
    ros.wait_for(lambda: any("resolution=352x288" in e.query for e in cam.request_counts.video_log), timeout=10)
    assert any("resolution=352x288" in e.query for e in cam.request_counts.video_log)
    assert math.isfinite(arrivals[-1])
