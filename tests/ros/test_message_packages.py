"""The message packages scripts/bootstrap builds from interfaces/ (tf2_msgs, ffmpeg_image_transport_msgs,
foxglove_msgs): field for field as upstream, and each message round-trips over DDS unchanged."""

from __future__ import annotations

from typing import Any

import pytest
from builtin_interfaces.msg import Time
from ffmpeg_image_transport_msgs.msg import FFMPEGPacket
from foxglove_msgs.msg import CompressedVideo
from geometry_msgs.msg import TransformStamped
from rclpy.qos import QoSDurabilityPolicy, QoSProfile, QoSReliabilityPolicy
from tf2_msgs.msg import TFMessage

pytestmark = [pytest.mark.ros, pytest.mark.timeout(120)]

# Upstream definitions: tf2_msgs/msg/TFMessage.msg (ros2/geometry2), FFMPEGPacket.msg
# (ros-misc-utilities/ffmpeg_image_transport_msgs), CompressedVideo.msg (foxglove_msgs as released for Jazzy)
UPSTREAM: dict[type, dict[str, str]] = {
    TFMessage: {"transforms": "sequence<geometry_msgs/TransformStamped>"},
    FFMPEGPacket: {
        "header": "std_msgs/Header",
        "width": "int32",
        "height": "int32",
        "encoding": "string",
        "pts": "uint64",
        "flags": "uint8",
        "is_bigendian": "boolean",
        "data": "sequence<uint8>",
    },
    CompressedVideo: {
        "timestamp": "builtin_interfaces/Time",
        "frame_id": "string",
        "data": "sequence<uint8>",
        "format": "string",
    },
}


@pytest.mark.parametrize("msg_type", list(UPSTREAM), ids=lambda t: t.__name__)
def test_fields_are_upstream_field_for_field(msg_type):
    assert msg_type.get_fields_and_field_types() == UPSTREAM[msg_type]  # names, types and order


def tf_message() -> TFMessage:
    out = TFMessage()
    for i, (parent, child) in enumerate((("base_link", "axis_ptz_base"), ("axis_ptz_base", "axis_ptz_pan_link"))):
        t = TransformStamped()
        t.header.stamp = Time(sec=1700000000 + i, nanosec=123456789)
        t.header.frame_id, t.child_frame_id = parent, child
        t.transform.translation.x, t.transform.translation.y, t.transform.translation.z = -0.214, 0.044 * i, 0.455
        t.transform.rotation.z, t.transform.rotation.w = 0.38268343236508984, 0.9238795325112867
        out.transforms.append(t)
    return out


def ffmpeg_packet() -> FFMPEGPacket:
    m = FFMPEGPacket()
    m.header.stamp = Time(sec=1700000000, nanosec=42)
    m.header.frame_id = "axis_ptz_optical_frame"
    m.width, m.height = 704, 576
    m.encoding = "h264;yuv420p;bgr8;bgr8"
    m.pts = 2**40 + 7  # beyond 32 bits: a uint64 really
    m.flags = 1  # key frame
    m.is_bigendian = False
    m.data = bytes([0, 0, 0, 1, 0x67, 0x42, 0xC0, 0x1E, 0, 0, 0, 1, 0x68, 0xCE, 0x3C, 0x80, 0, 0, 0, 1, 0x65, 0x88])
    return m


def compressed_video() -> CompressedVideo:
    m = CompressedVideo()
    m.timestamp = Time(sec=1700000001, nanosec=999999999)
    m.frame_id = "axis_ptz_optical_frame"
    m.data = bytes(range(256)) * 40
    m.format = "h264"
    return m


@pytest.mark.parametrize(
    ("topic", "build"),
    [("tf", tf_message), ("video/ffmpeg", ffmpeg_packet), ("video/compressed_video", compressed_video)],
    ids=["TFMessage", "FFMPEGPacket", "CompressedVideo"],
)
def test_round_trip_over_dds(ros, topic, build):
    """Publisher and subscriber in two contexts (two DDS participants): the message is serialised, sent and
    deserialised by the generated type support."""
    sent = build()
    qos = QoSProfile(depth=10, reliability=QoSReliabilityPolicy.RELIABLE, durability=QoSDurabilityPolicy.VOLATILE)
    name = type(sent).__name__.lower()
    got: list[Any] = []
    ros.probe(f"msgpkg_sub_{name}").create_subscription(type(sent), topic, got.append, qos)
    other = type(ros)()  # a second harness: its own context and participant
    try:
        pub = other.probe(f"msgpkg_pub_{name}").create_publisher(type(sent), topic, qos)
        ros.wait_for(lambda: pub.get_subscription_count() > 0, timeout=20.0)
        pub.publish(sent)
        ros.wait_for(lambda: got, timeout=20.0)
    finally:
        other.close()
    assert got[0] == sent  # every field, nested messages and byte arrays included
