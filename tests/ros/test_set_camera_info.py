"""camera_info_manager semantics on axis_stream over real DDS: ``camera_info_url`` + ``set_camera_info``.

A calibration stored through the service (what camera_calibration's "commit" calls) is written to the URL,
becomes the published camera_info's K and D at once, scales from the zoom it was taken at and with the stream
size, and is loaded again by a new node. Refusals (wrong matrix sizes, a size other than the stream's, an
unknown URL scheme) answer ``success=False`` with the reason and keep the previous calibration and file.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator

import pytest

pytest.importorskip("rclpy")

from rcl_interfaces.srv import SetParameters  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from sensor_msgs.msg import CameraInfo  # noqa: E402
from sensor_msgs.srv import SetCameraInfo  # noqa: E402

from axis_ptz_interfaces.msg import PtzState  # noqa: E402
from axis_ptz_ros2.camera_info_store import ZOOM_COMMENT  # noqa: E402
from axis_ptz_ros2.nodes.common import STREAM_QOS  # noqa: E402
from axis_ptz_ros2.nodes.stream_node import StreamNode  # noqa: E402
from axis_ptz_ros2.sim import SimulatedCamera  # noqa: E402
from tests.support.harness import RosHarness  # noqa: E402
from tests.support.models import AXIS_214_ZOOM  # noqa: E402

pytestmark = pytest.mark.ros

FAST = {"backoff_initial": 0.05, "backoff_max": 0.3, "stall_timeout": 0.4, "read_timeout": 2.0}
ZOOM_AT_CALIBRATION = 3000.0
D = [-0.21, 0.07, 0.0012, -0.0008, 0.0]


@pytest.fixture(scope="module")
def camera() -> Iterator[SimulatedCamera]:
    cam = SimulatedCamera(host="127.0.0.1", port=0).start()
    try:
        yield cam
    finally:
        cam.stop()


class Infos:
    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.items: list[CameraInfo] = []

    def __call__(self, msg: CameraInfo) -> None:
        with self.lock:
            self.items.append(msg)

    def last(self) -> CameraInfo | None:
        with self.lock:
            return self.items[-1] if self.items else None


def start(ros: RosHarness, camera: SimulatedCamera, url: str) -> tuple[Infos, object, object]:
    params = {"port": camera.port, "fps": 10, "resolution": "704x576", "zoom": 1.0, "camera_info_url": url, **FAST}
    ros.add(StreamNode(context=ros.context, parameter_overrides=[Parameter(k, value=v) for k, v in params.items()]))
    probe = ros.probe()
    infos = Infos()
    probe.create_subscription(CameraInfo, "camera_info", infos, STREAM_QOS)
    ros.wait_for(lambda: infos.last() is not None, timeout=10)
    return infos, probe, probe.create_client(SetCameraInfo, "/axis_stream/set_camera_info")


def calibration(width: int = 704, height: int = 576, fx: float = 1100.0) -> CameraInfo:
    ci = CameraInfo(width=width, height=height, distortion_model="plumb_bob")
    fy, cx, cy = fx * 1.004, width / 2 + 7.5, height / 2 - 4.25
    ci.k = [fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0]
    ci.d = list(D)
    ci.r = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
    ci.p = [fx, 0.0, cx, 0.0, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0]
    return ci


def set_info(ros: RosHarness, client, ci: CameraInfo) -> SetCameraInfo.Response:
    return ros.call(client, SetCameraInfo.Request(camera_info=ci))


def zoom_to(ros: RosHarness, probe, infos: Infos, zoom: float, fx: float) -> CameraInfo:
    pub = probe.create_publisher(PtzState, "ptz/state", STREAM_QOS)
    ros.wait_for(lambda: (pub.publish(PtzState(zoom=zoom)), abs(infos.last().k[0] - fx) < 1e-6 * fx)[1], timeout=5)
    return infos.last()


def test_stored_calibration_is_published_scaled_with_zoom_and_size_and_reloaded(ros, camera, tmp_path):
    url = f"file://{tmp_path}/calib/${{NAME}}.yaml"
    infos, probe, client = start(ros, camera, url)
    nominal = infos.last()
    assert list(nominal.d) == [0.0] * 5

    zoom_to(ros, probe, infos, ZOOM_AT_CALIBRATION, AXIS_214_ZOOM.intrinsics(ZOOM_AT_CALIBRATION, 704, 576).fx)
    ci = calibration()
    res = set_info(ros, client, ci)
    assert res.success, res.status_message
    path = tmp_path / "calib" / "axis_ptz.yaml"
    text = path.read_text(encoding="utf-8")
    assert f"{ZOOM_COMMENT} {ZOOM_AT_CALIBRATION!r}" in text
    assert "camera_name: axis_ptz" in text

    # at the zoom it was taken at: exactly the stored K and D
    ros.wait_for(lambda: abs(infos.last().k[0] - ci.k[0]) < 1e-9, timeout=5)
    got = infos.last()
    assert list(got.k) == pytest.approx(list(ci.k), rel=1e-12)
    assert list(got.d) == pytest.approx(D, rel=1e-12)
    assert got.distortion_model == "plumb_bob"

    # another zoom: focal scaled by the magnification ratio, principal point and distortion kept
    ratio = AXIS_214_ZOOM.magnification(8000.0) / AXIS_214_ZOOM.magnification(ZOOM_AT_CALIBRATION)
    zoomed = zoom_to(ros, probe, infos, 8000.0, ci.k[0] * ratio)
    assert zoomed.k[4] == pytest.approx(ci.k[4] * ratio, rel=1e-9)
    assert (zoomed.k[2], zoomed.k[5]) == pytest.approx((ci.k[2], ci.k[5]), rel=1e-9)
    assert list(zoomed.d) == pytest.approx(D, rel=1e-12)

    # half the stream size: everything in pixels halves
    set_params = probe.create_client(SetParameters, "/axis_stream/set_parameters")
    req = SetParameters.Request(parameters=[Parameter("resolution", value="352x288").to_parameter_msg()])
    assert ros.call(set_params, req).results[0].successful
    ros.wait_for(lambda: infos.last().width == 352, timeout=5)
    half = infos.last()
    assert half.k[0] == pytest.approx(zoomed.k[0] / 2, rel=1e-6)
    assert half.k[2] == pytest.approx((ci.k[2] + 0.5) / 2 - 0.5, rel=1e-6)

    # a new node on the same URL starts with it
    for n in list(ros.nodes):
        ros.executor.remove_node(n)
        n.destroy_node()
        ros.nodes.remove(n)
    infos2, probe2, _ = start(ros, camera, url)
    zoom_to(ros, probe2, infos2, ZOOM_AT_CALIBRATION, ci.k[0])
    assert list(infos2.last().d) == pytest.approx(D, rel=1e-12)


def _resize(ci: CameraInfo, width: int, height: int) -> None:
    """A self-consistent calibration of another size (only the size is wrong)."""
    other = calibration(width, height, fx=ci.k[0] * width / ci.width)
    ci.width, ci.height, ci.k, ci.p = other.width, other.height, other.k, other.p


@pytest.mark.parametrize(
    ("change", "reason"),
    [
        # K, R, P are fixed-size arrays in the message; D is the one matrix whose size can be wrong
        (lambda ci: setattr(ci, "d", [0.1, -0.05, 0.01]), "plumb_bob needs 5 distortion coefficients, got 3"),
        (lambda ci: setattr(ci, "d", [*D, 0.3, 0.1, 0.2]), "only the first 5 distortion coefficients"),
        (lambda ci: setattr(ci, "distortion_model", "fisheye_x"), "distortion_model 'fisheye_x' is not supported"),
        (lambda ci: _resize(ci, 352, 288), "calibration is 352x288 but the stream is 704x576"),
        (lambda ci: setattr(ci, "k", [0.0] * 9), "fx and fy must be positive"),
    ],
    ids=["d-short", "d-long", "model", "stream-size", "zero-focal"],
)
def test_bad_calibration_refused_with_reason_previous_kept(ros, camera, tmp_path, change, reason):
    infos, probe, client = start(ros, camera, f"file://{tmp_path}/${{NAME}}.yaml")
    good = calibration(fx=1000.0)
    assert set_info(ros, client, good).success
    path = tmp_path / "axis_ptz.yaml"
    before = path.read_bytes()
    ros.wait_for(lambda: list(infos.last().d) == pytest.approx(D), timeout=5)
    published = list(infos.last().k)

    bad = calibration(fx=1500.0)
    change(bad)
    res = set_info(ros, client, bad)
    assert not res.success
    assert reason in res.status_message, res.status_message
    assert res.status_message.startswith("refused"), res.status_message
    assert path.read_bytes() == before  # the file is untouched
    n = len(infos.items)
    ros.wait_for(lambda: len(infos.items) >= n + 5, timeout=5)
    assert list(infos.last().k) == published  # the previous calibration is still the one published


def test_unknown_url_scheme_refused_node_keeps_running(ros, camera, tmp_path):
    infos, _probe, client = start(ros, camera, "http://example.invalid/axis.yaml")
    res = set_info(ros, client, calibration())
    assert not res.success
    assert "unsupported scheme 'http://'" in res.status_message, res.status_message
    n = len(infos.items)
    ros.wait_for(lambda: len(infos.items) >= n + 3, timeout=5)
    assert list(infos.last().d) == [0.0] * 5  # still the model's calibration


def test_malformed_file_at_start_keeps_model_and_is_replaced_by_a_good_one(ros, camera, tmp_path):
    path = tmp_path / "axis_ptz.yaml"
    path.write_text("image_width: 704\ncamera_matrix: [oops\n", encoding="utf-8")
    infos, _probe, client = start(ros, camera, f"file://{path}")
    assert list(infos.last().d) == [0.0] * 5
    res = set_info(ros, client, calibration())
    assert res.success, res.status_message
    assert "camera_matrix" in path.read_text(encoding="utf-8")
    ros.wait_for(lambda: list(infos.last().d) == pytest.approx(D), timeout=5)
