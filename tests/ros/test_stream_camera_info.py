"""axis_stream publishes a measured camera_info (from the camera model) over real DDS.

The camera model references a ROS camera calibration YAML measured at zoom 1 (704×576, principal point off
centre, plumb_bob distortion). The published ``camera_info`` must carry those K, D, distortion_model and P at
zoom 1 and full resolution, keep the principal point and distortion at another zoom (focal scaled with the
zoom curve), and scale with the stream resolution.
"""

from __future__ import annotations

import threading

import pytest

pytest.importorskip("rclpy")

from rclpy.parameter import Parameter  # noqa: E402
from sensor_msgs.msg import CameraInfo  # noqa: E402

from axis_ptz_interfaces.msg import PtzState  # noqa: E402
from axis_ptz_ros2.calibration.synthetic import real_like_camera_info  # noqa: E402
from axis_ptz_ros2.camera_info import save_camera_info  # noqa: E402
from axis_ptz_ros2.config import default_config_path  # noqa: E402
from axis_ptz_ros2.nodes.common import STREAM_QOS  # noqa: E402
from axis_ptz_ros2.nodes.stream_node import StreamNode  # noqa: E402
from axis_ptz_ros2.sim import SimulatedCamera  # noqa: E402
from tests.support.models import AXIS_214_ZOOM  # noqa: E402

pytestmark = pytest.mark.ros


def collect_camera_info(probe) -> tuple[list[CameraInfo], threading.Lock]:  # noqa: ANN001
    """Every ``camera_info`` the probe receives, in order, and the lock to read them under."""
    infos: list[CameraInfo] = []
    lock = threading.Lock()

    def on_info(msg: CameraInfo) -> None:
        with lock:
            infos.append(msg)

    probe.create_subscription(CameraInfo, "camera_info", on_info, STREAM_QOS)
    return infos, lock


def test_stream_publishes_the_measured_camera_info(ros, tmp_path):
    measured = real_like_camera_info("plumb_bob", 704, 576)
    save_camera_info(measured, tmp_path / "ost.yaml")
    model = tmp_path / "model.yaml"
    model.write_text(
        default_config_path("axis214.yaml").read_text(encoding="utf-8") + "camera_info: ost.yaml\n", encoding="utf-8"
    )
    cam = SimulatedCamera(host="127.0.0.1", port=0).start()
    try:
        params = {"port": cam.port, "fps": 10, "resolution": "704x576", "zoom": 1.0, "camera_model": str(model)}
        ros.add(StreamNode(context=ros.context, parameter_overrides=[Parameter(k, value=v) for k, v in params.items()]))
        probe = ros.probe()
        infos, lock = collect_camera_info(probe)
        ros.wait_for(lambda: len(infos) >= 2, timeout=10)
        with lock:
            info = infos[-1]
        assert (info.width, info.height) == (704, 576)
        assert info.distortion_model == "plumb_bob"
        assert list(info.d) == pytest.approx(list(measured.D))
        assert list(info.k) == pytest.approx(list(measured.K))
        assert list(info.p) == pytest.approx(list(measured.P))
        assert info.k[2] != pytest.approx((704 - 1) / 2)  # really the measured, off-centre principal point

        # another zoom: focal scaled by the zoom curve's magnification, principal point and distortion kept
        pub = probe.create_publisher(PtzState, "ptz/state", STREAM_QOS)
        m = AXIS_214_ZOOM.magnification(4000.0)
        want = measured.fx * m

        def zoomed() -> bool:
            pub.publish(PtzState(zoom=4000.0))
            with lock:
                return infos[-1].k[0] == pytest.approx(want)

        ros.wait_for(zoomed, timeout=5)
        with lock:
            z = infos[-1]
        assert z.k[4] == pytest.approx(measured.fy * m)
        assert (z.k[2], z.k[5]) == pytest.approx((measured.cx, measured.cy))
        assert list(z.d) == pytest.approx(list(measured.D))
    finally:
        cam.stop()


def test_axis_camera_feeds_camera_info_the_ptz_nodes_zoom_in_process(ros):
    # axis_camera's pair: the stream node has no ptz/state subscription (20 Hz deserialised for one number); its
    # camera_info still follows the zoom the PTZ node polls from the camera
    from axis_ptz_interfaces.msg import PtzCommand
    from axis_ptz_ros2.nodes.camera_main import camera_pair
    from axis_ptz_ros2.nodes.common import COMMAND_QOS

    cam = SimulatedCamera(host="127.0.0.1", port=0).start()
    try:
        params = {"port": cam.port, "fps": 10, "resolution": "704x576", "zoom": 1.0}
        overrides = [Parameter(k, value=v) for k, v in params.items()]
        make_stream, make_ptz = camera_pair(None, context=ros.context, parameter_overrides=overrides)
        stream = ros.add(make_stream())
        ros.add(make_ptz())
        probe = ros.probe()
        infos, lock = collect_camera_info(probe)
        ros.wait_for(lambda: len(infos) >= 2, timeout=10)
        readers = {i.node_name for i in probe.get_subscriptions_info_by_topic("/ptz/state")}
        assert stream.get_name() not in readers, readers
        model = stream.camera_model
        fx = {z: model.camera_info_at(z, 704, 576).intrinsics().fx for z in (1.0, 4000.0)}
        assert fx[4000.0] > 1.5 * fx[1.0]
        with lock:
            assert infos[-1].k[0] == pytest.approx(fx[1.0])
        pub = probe.create_publisher(PtzCommand, "ptz/cmd/absolute", COMMAND_QOS)
        nan = float("nan")

        def zoomed() -> bool:
            pub.publish(PtzCommand(pan=nan, tilt=nan, zoom=4000.0, speed=nan))
            with lock:
                return infos[-1].k[0] == pytest.approx(fx[4000.0], rel=1e-3)

        ros.wait_for(zoomed, timeout=15, period=0.2)
    finally:
        cam.stop()
