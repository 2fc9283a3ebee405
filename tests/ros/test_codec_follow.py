"""One codec decision across the link (issue 40 item 3): ``axis_link_monitor``, ``axis_republish`` and the web
console at their default (``auto``) follow the codec the stream node announces on ``video/params``.

Over real DDS; what each tool subscribes to is read from the ROS graph (the DDS discovery data of its node), not
from the node's own bookkeeping. The stream node runs against the simulated camera (in-process, port 0); a stream
whose codec parameter is set at runtime makes each tool drop the old topic and subscribe to the new one.
"""

from __future__ import annotations

import http.client
import json
from typing import Any

import pytest

pytest.importorskip("rclpy")

from rcl_interfaces.srv import SetParameters  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from sensor_msgs.msg import Image  # noqa: E402

from axis_ptz_interfaces.msg import LinkFeedback, VideoParams  # noqa: E402
from axis_ptz_ros2.nodes.common import FEEDBACK_QOS, LATCHED_QOS, STREAM_QOS  # noqa: E402
from axis_ptz_ros2.nodes.link_monitor import LinkMonitorNode  # noqa: E402
from axis_ptz_ros2.nodes.republish import RepublishNode  # noqa: E402
from axis_ptz_ros2.nodes.web_console import WebConsole  # noqa: E402
from axis_ptz_ros2.sim import SimulatedCamera  # noqa: E402
from tests.support.harness import RosHarness  # noqa: E402
from tests.support.stream_node import make_stream_node  # noqa: E402
from tests.support.waiting import unchanged_for  # noqa: E402

pytestmark = pytest.mark.ros

JPEG_TOPIC = "/image_raw/compressed"
H264_TOPIC = "/image_raw/ffmpeg"
VIDEO = {JPEG_TOPIC, H264_TOPIC}
H264 = {"codec": "h264", "resolution": "352x288", "fps": 10}


# the simulated camera: `sim` (one per module) and `camera` (reset per test) come from tests/ros/conftest.py


def set_stream(ros: RosHarness, probe: Node, **values: object) -> None:
    client = probe.create_client(SetParameters, "/axis_stream/set_parameters")
    req = SetParameters.Request()
    req.parameters = [Parameter(k, value=v).to_parameter_msg() for k, v in values.items()]
    results = ros.call(client, req).results
    assert all(r.successful for r in results), [r.reason for r in results]


def video_subscriptions(probe: Node, node_name: str) -> set[str]:
    """The video topics ``node_name`` subscribes to, as the ROS graph tells."""
    topics = {t for t, _types in probe.get_subscriber_names_and_types_by_node(node_name, "/")}
    return topics & VIDEO


def subscribers(probe: Node, topic: str, node_name: str) -> int:
    """How many subscriptions of ``node_name`` the graph lists on ``topic`` (DDS endpoint data)."""
    return sum(1 for i in probe.get_subscriptions_info_by_topic(topic) if i.node_name == node_name)


def only(probe: Node, node_name: str, topic: str) -> bool:
    """``node_name`` subscribes to ``topic`` (once) and to no other video topic."""
    return video_subscriptions(probe, node_name) == {topic} and all(
        subscribers(probe, t, node_name) == (1 if t == topic else 0) for t in VIDEO
    )


# ---------------------------------------------------------------------------------------------------------
# the link monitor
# ---------------------------------------------------------------------------------------------------------
def test_link_monitor_follows_the_streams_codec_and_switches_with_it(ros: RosHarness, camera: SimulatedCamera) -> None:
    make_stream_node(ros, camera, **H264)
    monitor = ros.add(LinkMonitorNode(context=ros.context))  # the default: codec auto
    probe = ros.probe()
    reports: list[LinkFeedback] = []
    probe.create_subscription(LinkFeedback, "video/feedback", reports.append, FEEDBACK_QOS)

    ros.wait_for(lambda: only(probe, "axis_link_monitor", H264_TOPIC), 10.0)
    ros.wait_for(lambda: _watched(reports, H264_TOPIC), 15.0)
    assert monitor.receiver is not None
    assert monitor.receiver.stats.pictures > 3
    assert subscribers(probe, JPEG_TOPIC, "axis_link_monitor") == 0

    set_stream(ros, probe, codec="mjpeg")  # at runtime (what `ros2 param set` does)
    ros.wait_for(lambda: only(probe, "axis_link_monitor", JPEG_TOPIC), 10.0)
    n = len(reports)
    ros.wait_for(lambda: _watched(reports[n:], JPEG_TOPIC), 15.0)
    assert monitor.receiver is None

    set_stream(ros, probe, codec="h264")
    ros.wait_for(lambda: only(probe, "axis_link_monitor", H264_TOPIC), 10.0)
    n = len(reports)
    ros.wait_for(lambda: _watched(reports[n:], H264_TOPIC), 15.0)


def _watched(reports: list[LinkFeedback], topic: str) -> bool:
    """A report of frames received on ``topic`` (its ``header.frame_id``) among ``reports``."""
    return any(r.frames > 3 and r.header.frame_id == topic for r in list(reports))


def test_link_monitor_waits_for_video_params_and_follows_what_it_announces(ros: RosHarness) -> None:
    """No stream node: until ``video/params`` is heard, no video subscription and no report (a report of nothing
    received would read as a dead link to the stream node); then what a (probe) stream announces, also a codec
    it cannot follow (nothing watched)."""
    monitor = ros.add(LinkMonitorNode(context=ros.context, parameter_overrides=[Parameter("period", value=0.05)]))
    probe = ros.probe()
    reports: list[LinkFeedback] = []
    probe.create_subscription(LinkFeedback, "video/feedback", reports.append, FEEDBACK_QOS)
    ros.wait_for(
        lambda: "/video/params" in dict(probe.get_subscriber_names_and_types_by_node("axis_link_monitor", "/"))
    )
    # a quiet window of 20 report periods: no video subscription appears, no report goes out
    ros.wait_for(unchanged_for(lambda: (frozenset(video_subscriptions(probe, "axis_link_monitor")), len(reports)), 1.0))
    assert video_subscriptions(probe, "axis_link_monitor") == set()
    assert reports == []
    assert monitor.codec == ""

    pub = probe.create_publisher(VideoParams, "video/params", LATCHED_QOS)
    for codec, topic in (("h264", H264_TOPIC), ("mjpeg", JPEG_TOPIC)):
        pub.publish(VideoParams(codec=codec, fps=10, width=352, height=288, resolution="352x288"))
        ros.wait_for(lambda topic=topic: only(probe, "axis_link_monitor", topic), 10.0)
        assert monitor.codec == codec
    pub.publish(VideoParams(codec="vp9"))  # a codec it cannot follow: watch nothing rather than guess
    ros.wait_for(lambda: video_subscriptions(probe, "axis_link_monitor") == set(), 10.0)
    assert "vp9" in monitor.follower.problem


def test_link_monitor_refuses_an_unknown_codec_with_the_reason(ros: RosHarness) -> None:
    with pytest.raises(ValueError, match=r"codec='mjpg' is not one of auto, mjpeg, h264"):
        LinkMonitorNode(context=ros.context, parameter_overrides=[Parameter("codec", value="mjpg")])


def test_link_monitor_with_an_explicit_codec_keeps_it(ros: RosHarness, camera: SimulatedCamera) -> None:
    """``codec: mjpeg`` is the operator's choice: the stream's H.264 announcement changes nothing."""
    make_stream_node(ros, camera, **H264)
    monitor = ros.add(LinkMonitorNode(context=ros.context, parameter_overrides=[Parameter("codec", value="mjpeg")]))
    probe = ros.probe()
    ros.wait_for(lambda: only(probe, "axis_link_monitor", JPEG_TOPIC), 10.0)
    assert "/video/params" not in dict(probe.get_subscriber_names_and_types_by_node("axis_link_monitor", "/"))
    assert monitor.codec == "mjpeg"


# ---------------------------------------------------------------------------------------------------------
# the republisher
# ---------------------------------------------------------------------------------------------------------
def test_republisher_follows_the_streams_codec_and_switches_with_it(ros: RosHarness, camera: SimulatedCamera) -> None:
    make_stream_node(ros, camera, **H264)
    rep = ros.add(RepublishNode(context=ros.context))  # the default: input auto, lazy
    probe = ros.probe()
    images: list[Image] = []
    probe.create_subscription(Image, "image_raw", images.append, STREAM_QOS)

    ros.wait_for(lambda: only(probe, "axis_republish", H264_TOPIC), 10.0)
    ros.wait_for(lambda: len(images) >= 3, 15.0)
    assert (images[-1].width, images[-1].height) == (352, 288)
    assert rep.codec == "h264"

    set_stream(ros, probe, codec="mjpeg")
    ros.wait_for(lambda: only(probe, "axis_republish", JPEG_TOPIC), 10.0)
    decoded = rep.decoded
    ros.wait_for(lambda: rep.decoded >= decoded + 3, 15.0)  # decoding JPEGs now

    set_stream(ros, probe, codec="h264")
    ros.wait_for(lambda: only(probe, "axis_republish", H264_TOPIC), 10.0)
    decoded = rep.decoded
    ros.wait_for(lambda: rep.decoded >= decoded + 3, 15.0)
    assert rep.failed == 0


def test_republisher_refuses_an_unknown_input_with_the_reason(ros: RosHarness) -> None:
    with pytest.raises(ValueError, match=r"input='mjpg' is not one of auto, jpeg, h264"):
        RepublishNode(context=ros.context, parameter_overrides=[Parameter("input", value="mjpg")])


# ---------------------------------------------------------------------------------------------------------
# the web console
# ---------------------------------------------------------------------------------------------------------
def _state(console: WebConsole) -> dict[str, Any]:
    conn = http.client.HTTPConnection("127.0.0.1", console.server.port, timeout=10)
    try:
        conn.request("GET", "/api/state")
        resp = conn.getresponse()
        assert resp.status == 200
        return dict(json.loads(resp.read()))
    finally:
        conn.close()


class _Watcher:
    """One HTTP client watching a console video route (the console subscribes while one watches)."""

    def __init__(self, console: WebConsole, path: str) -> None:
        self.conn = http.client.HTTPConnection("127.0.0.1", console.server.port, timeout=10)
        self.conn.request("GET", path)
        self.resp = self.conn.getresponse()
        self.status = self.resp.status
        self.body = b"" if self.status == 200 else self.resp.read()

    def close(self) -> None:
        self.resp.close()
        self.conn.close()


def test_web_console_follows_the_streams_codec_and_switches_with_it(ros: RosHarness, camera: SimulatedCamera) -> None:
    make_stream_node(ros, camera, **H264)
    console = ros.add(WebConsole(context=ros.context, parameter_overrides=[Parameter("port", value=0)]))
    probe = ros.probe()
    ros.wait_for(lambda: _state(console)["ptz_video"]["codec"] == "h264", 10.0)
    assert _state(console)["h264"]["available"]

    h264 = _Watcher(console, "/video/ptz.h264")
    try:
        assert h264.status == 200
        ros.wait_for(lambda: only(probe, "axis_web_console", H264_TOPIC), 10.0)
        ros.wait_for(lambda: _state(console)["h264"]["keys"] >= 1, 15.0)  # the relay gets the stream's H.264

        set_stream(ros, probe, codec="mjpeg")  # the H.264 subscription goes with the stream's H.264
        ros.wait_for(lambda: _state(console)["ptz_video"]["codec"] == "mjpeg", 10.0)
        ros.wait_for(lambda: video_subscriptions(probe, "axis_web_console") == set(), 10.0)
        assert not _state(console)["h264"]["available"]
        refused = _Watcher(console, "/video/ptz.h264")  # a page asking for H.264 now is told why not
        assert refused.status == 404
        assert b"MJPEG" in refused.body, refused.body
        refused.close()
        mjpeg = _Watcher(console, "/video/ptz.mjpg")
        try:
            ros.wait_for(lambda: only(probe, "axis_web_console", JPEG_TOPIC), 10.0)
        finally:
            mjpeg.close()
        ros.wait_for(lambda: video_subscriptions(probe, "axis_web_console") == set(), 10.0)

        set_stream(ros, probe, codec="h264")  # the open H.264 request is served again
        ros.wait_for(lambda: _state(console)["ptz_video"]["codec"] == "h264", 10.0)
        ros.wait_for(lambda: only(probe, "axis_web_console", H264_TOPIC), 10.0)
    finally:
        h264.close()


def test_web_console_waits_for_video_params_and_refuses_an_unknown_codec(ros: RosHarness) -> None:
    console = ros.add(WebConsole(context=ros.context, parameter_overrides=[Parameter("port", value=0)]))
    state = _state(console)["ptz_video"]
    assert (state["codec"], state["choice"]) == ("", "auto")
    assert "video/params" in state["text"]
    assert not _state(console)["h264"]["available"]
    with pytest.raises(ValueError, match=r"codec='H264' is not one of auto, mjpeg, h264"):
        WebConsole(
            context=ros.context, parameter_overrides=[Parameter("port", value=0), Parameter("codec", value="H264")]
        )
