"""The stream node's parameter services come after its video publishers (docs/weak-link.md, "The video publishers'
discovery data first"), and they still answer."""

from __future__ import annotations

import pytest

pytest.importorskip("rclpy")

import rclpy  # noqa: E402
from rcl_interfaces.srv import GetParameters  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402

from axis_ptz_ros2.nodes.stream_node import StreamNode  # noqa: E402
from tests.support.stream_node import make_stream_node  # noqa: E402

pytestmark = pytest.mark.ros


def test_parameter_services_are_served_and_can_be_left_out(ros, camera):
    """The node starts its parameter services itself, after its video publishers (their discovery data then
    crosses a lossy link first: docs/weak-link.md); ``start_parameter_services=False`` leaves them out as for any
    rclpy node."""
    node = make_stream_node(ros, camera)
    quiet = StreamNode(
        "axis_stream_quiet",
        context=ros.context,
        start_parameter_services=False,
        parameter_overrides=[Parameter("port", value=camera.port)],
    )
    ros.add(quiet)
    probe = ros.probe()
    services = lambda n: {name for name, _ in probe.get_service_names_and_types_by_node(n, "/")}  # noqa: E731
    ros.wait_for(lambda: "/axis_stream/get_parameters" in services("axis_stream"), timeout=10)
    client = probe.create_client(GetParameters, "/axis_stream/get_parameters")
    assert client.wait_for_service(timeout_sec=5)
    got = ros.call(client, GetParameters.Request(names=["fps"]))
    assert got.values[0].integer_value == node.live_params.params["fps"]
    ros.wait_for(lambda: "/video/set_params" in services("axis_stream_quiet"), timeout=10)  # its own
    assert not any("parameter" in s for s in services("axis_stream_quiet")), services("axis_stream_quiet")


def test_video_publishers_are_made_before_the_parameter_services(ros, camera):
    """Fast DDS numbers a participant's endpoints as they are made and sends a newcomer their discovery data in that
    order: the video writers' entity keys come before every parameter service's reply writer, so a lost discovery
    packet behind them does not hold them up (docs/weak-link.md). rclpy alone makes the services first."""
    if "fastrtps" not in rclpy.get_rmw_implementation_identifier():
        pytest.skip("entity keys in creation order are Fast DDS's numbering")
    make_stream_node(ros, camera)
    probe = ros.probe()

    def gids(topic: str, raw: bool = False) -> list[bytes]:
        return [bytes(i.endpoint_gid) for i in probe.get_publishers_info_by_topic(topic, no_mangle=raw)]

    replies = [f"rr/axis_stream/{s}Reply" for s in ("get_parameters", "set_parameters", "list_parameters")]
    ros.wait_for(lambda: all(gids(t, raw=True) for t in replies), timeout=10)
    node_replies = [g for t in replies for g in gids(t, raw=True)]
    participant = node_replies[0][:12]  # the GUID prefix; the entity key is the next 3 bytes
    first_service = min(int.from_bytes(g[12:15], "big") for g in node_replies)
    for topic in ("/image_raw/compressed", "/image_raw/ffmpeg", "/image_raw/foxglove"):
        ros.wait_for(lambda topic=topic: [g for g in gids(topic) if g[:12] == participant], timeout=10)
        keys = [int.from_bytes(g[12:15], "big") for g in gids(topic) if g[:12] == participant]
        assert max(keys) < first_service, (topic, keys, first_service)
