"""axis_republish over real DDS: JPEG → bgr8 only while image_raw has subscribers."""

from __future__ import annotations

import time

import cv2
import numpy as np
import pytest

pytest.importorskip("rclpy")

from rclpy.parameter import Parameter  # noqa: E402
from sensor_msgs.msg import CompressedImage, Image  # noqa: E402

from axis_ptz_ros2.nodes.common import STREAM_QOS  # noqa: E402
from axis_ptz_ros2.nodes.republish import RepublishNode  # noqa: E402

pytestmark = pytest.mark.ros


def test_decodes_only_while_someone_subscribes(ros):
    # input jpeg: the topic is published by this test, not by a stream node announcing its codec on video/params
    node = ros.add(RepublishNode(context=ros.context, parameter_overrides=[Parameter("input", value="jpeg")]))
    probe = ros.probe()
    pub = probe.create_publisher(CompressedImage, "image_raw/compressed", STREAM_QOS)
    time.sleep(0.5)  # a window for a (wrong) subscription with nobody on image_raw: the thing under test is none
    assert probe.count_subscribers("image_raw/compressed") == 0, "subscribed with nobody on image_raw"
    assert not node.subscribed

    rng = np.random.default_rng(3)
    src = cv2.resize(rng.integers(0, 255, (9, 11, 3), dtype=np.uint8), (176, 144), interpolation=cv2.INTER_NEAREST)
    ok, jpg = cv2.imencode(".jpg", src, [cv2.IMWRITE_JPEG_QUALITY, 95])
    assert ok
    msg = CompressedImage(format="jpeg", data=jpg.tobytes())
    msg.header.frame_id = "axis_ptz_optical_frame"
    msg.header.stamp.sec = 123
    msg.header.stamp.nanosec = 456

    got: list[Image] = []
    sub = probe.create_subscription(Image, "image_raw", got.append, STREAM_QOS)
    ros.wait_for(lambda: probe.count_subscribers("image_raw/compressed") == 1, timeout=3)
    ros.wait_for(lambda: (pub.publish(msg), got)[1], timeout=3)
    img = got[-1]
    assert (img.width, img.height, img.encoding, img.step) == (176, 144, "bgr8", 176 * 3)
    assert (img.header.stamp.sec, img.header.stamp.nanosec) == (123, 456)
    assert img.header.frame_id == "axis_ptz_optical_frame"
    arr = np.frombuffer(img.data, np.uint8).reshape(144, 176, 3)
    expected = cv2.imdecode(jpg, cv2.IMREAD_COLOR)
    assert np.array_equal(arr, expected)
    assert np.abs(arr.astype(int) - src.astype(int)).mean() < 8  # and it is the picture that was sent

    # A broken JPEG is counted and publishes nothing. Messages from one publisher are handled in order, so once
    # it is counted every earlier repeat of the loop above has been decoded; a good one after it is a barrier.
    bad = CompressedImage(format="jpeg", data=b"\xff\xd8 not a jpeg")
    bad.header.stamp.sec = 999
    pub.publish(bad)
    ros.wait_for(lambda: node.failed == 1, timeout=3)
    decoded = node.decoded
    msg.header.stamp.sec = 777
    pub.publish(msg)
    ros.wait_for(lambda: any(g.header.stamp.sec == 777 for g in got), timeout=3)
    assert node.decoded == decoded + 1
    assert node.failed == 1
    assert not [g for g in got if g.header.stamp.sec == 999]

    probe.destroy_subscription(sub)
    ros.wait_for(lambda: probe.count_subscribers("image_raw/compressed") == 0, timeout=3)
    assert not node.subscribed
