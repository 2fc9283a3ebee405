"""Every JPEG the project publishes carries the ``CompressedImage.format`` that ``compressed_image_transport``
writes ("bgr8; jpeg compressed bgr8", or mono8 for a one-component JPEG), and decodes as its subscriber decodes
it: the encoding before ';' must describe what ``imdecode(IMREAD_UNCHANGED)`` returns, and "compressed bgr"
says no channel swap is needed. Checked on the messages of every publisher: the stream node (the camera's own
JPEG passed through), the panorama simulator, the virtual camera and the visualizer, over real DDS."""

from __future__ import annotations

import math
import threading
from collections.abc import Iterator
from typing import Any

import cv2
import numpy as np
import pytest

pytest.importorskip("rclpy")

from rclpy.parameter import Parameter  # noqa: E402
from sensor_msgs.msg import CompressedImage  # noqa: E402

from axis_ptz_interfaces.msg import PtzState  # noqa: E402
from axis_ptz_ros2.nodes.common import JPEG_FORMAT_BGR8, JPEG_FORMAT_MONO8, STREAM_QOS  # noqa: E402
from axis_ptz_ros2.nodes.panorama_sim import PanoramaSim  # noqa: E402
from axis_ptz_ros2.nodes.stream_node import StreamNode  # noqa: E402
from axis_ptz_ros2.nodes.virtual_camera import VirtualCameraNode  # noqa: E402
from axis_ptz_ros2.nodes.visualizer import Visualizer  # noqa: E402
from axis_ptz_ros2.sim import SimulatedCamera  # noqa: E402

pytestmark = [pytest.mark.ros, pytest.mark.timeout(180)]

CHANNELS = {"bgr8": 3, "mono8": 1}


@pytest.fixture(scope="module")
def camera() -> Iterator[SimulatedCamera]:
    cam = SimulatedCamera(host="127.0.0.1", port=0).start()
    try:
        yield cam
    finally:
        cam.stop()


def decode_as_compressed_image_transport(msg: CompressedImage) -> tuple[str, np.ndarray]:
    """compressed_image_transport's CompressedSubscriber::internalCallback (Jazzy), for JPEG: the encoding is
    the part before ';'; an image that is not in that encoding's channel count would be mislabelled."""
    img = cv2.imdecode(np.frombuffer(bytes(msg.data), np.uint8), cv2.IMREAD_UNCHANGED)
    assert img is not None, "not a decodable image"
    encoding, sep, rest = msg.format.partition(";")
    assert sep, f"format {msg.format!r}: no '<encoding>; jpeg compressed <target>' (the decoder would guess)"
    assert "jpeg compressed" in rest
    return encoding, img


def test_every_jpeg_publisher_uses_the_compressed_image_transport_format(ros: Any, camera: SimulatedCamera) -> None:
    ros.add(
        StreamNode(
            context=ros.context,
            namespace="cam",
            parameter_overrides=[Parameter("port", value=camera.port), Parameter("fps", value=5)],
        )
    )
    ros.add(
        PanoramaSim(
            context=ros.context, parameter_overrides=[Parameter("width", value=512), Parameter("rate", value=5.0)]
        )
    )
    virt = VirtualCameraNode(
        context=ros.context,
        namespace="virt",
        parameter_overrides=[
            Parameter("panorama_topic", value="/panorama/image_raw"),
            Parameter("width", value=320),
            Parameter("height", value=240),
        ],
    )
    ros.add(virt)
    ros.add(virt.ptz)
    ros.add(Visualizer(context=ros.context))  # fmt: skip
    probe = ros.probe()
    lock = threading.Lock()
    got: dict[str, CompressedImage] = {}

    def keep(topic: str) -> Any:
        def cb(msg: CompressedImage) -> None:
            with lock:
                got[topic] = msg

        return cb

    topics = ["/cam/image_raw/compressed", "/panorama/image_raw/compressed", "/virt/image_raw/compressed",
              "/axis_visualizer/compressed"]  # fmt: skip
    for t in topics:
        probe.create_subscription(CompressedImage, t, keep(t), STREAM_QOS)
    state_pub = probe.create_publisher(PtzState, "ptz/state", STREAM_QOS)
    state = PtzState(pan=0.3, tilt=0.1, zoom=1.0, hfov=math.radians(48.0), vfov=math.radians(37.0))
    state.header.frame_id = "axis_ptz_base"

    def all_in() -> bool:
        state_pub.publish(state)  # the visualizer draws only with a PTZ state
        with lock:
            return len(got) == len(topics)

    ros.wait_for(all_in, timeout=30, period=0.1)
    for t in topics:
        msg = got[t]
        assert msg.format in (JPEG_FORMAT_BGR8, JPEG_FORMAT_MONO8), f"{t}: {msg.format!r}"
        encoding, img = decode_as_compressed_image_transport(msg)
        channels = 1 if img.ndim == 2 else img.shape[2]
        assert CHANNELS[encoding] == channels, f"{t}: {msg.format!r} but the JPEG decodes to {channels} channel(s)"


def test_passed_through_camera_jpeg_is_labelled_by_its_components() -> None:
    """The stream node publishes the camera's bytes as they are: a greyscale camera JPEG (one component, as
    Axis cameras send with color=0) must be labelled mono8, or the decoder would mislabel a 1-channel image."""
    from axis_ptz_ros2.nodes.common import jpeg_format_of  # noqa: PLC0415

    colour = cv2.imencode(".jpg", np.full((48, 64, 3), (10, 200, 30), np.uint8))[1].tobytes()
    grey = cv2.imencode(".jpg", np.full((48, 64), 77, np.uint8))[1].tobytes()
    for data, want in ((colour, JPEG_FORMAT_BGR8), (grey, JPEG_FORMAT_MONO8)):
        msg = CompressedImage(format=jpeg_format_of(data))
        msg.data = data
        encoding, img = decode_as_compressed_image_transport(msg)
        assert msg.format == want
        assert CHANNELS[encoding] == (1 if img.ndim == 2 else img.shape[2])
