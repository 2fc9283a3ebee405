"""axis_stream choosing the size a camera's own H.264 is asked for (issue 39 item 6), over real DDS, against the
simulated current-Axis persona (q6075): with ``resolution`` auto, the largest 16:9 size the camera lists whose bits
per pixel per picture reach the threshold at the bitrate in force (streaming/passthrough_size.py); shown on
``video/params``; a lasting drop of the bitrate restarts the camera's session at a smaller size.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

pytest.importorskip("rclpy")

from axis_ptz_interfaces.msg import VideoParams  # noqa: E402
from axis_ptz_ros2.nodes.common import LATCHED_QOS  # noqa: E402
from axis_ptz_ros2.sim import SimulatedCamera  # noqa: E402
from axis_ptz_ros2.streaming.passthrough_size import MIN_BITS_PER_PIXEL, SizeConfig, bits_per_pixel  # noqa: E402
from axis_ptz_ros2.vapix.models import Resolution  # noqa: E402
from tests.ros.test_stream_h264 import set_params, subscribe  # noqa: E402
from tests.ros.test_stream_passthrough import PASSWORD, make_node  # noqa: E402
from tests.support.harness import RosHarness  # noqa: E402
from tests.support.waiting import wait_until  # noqa: E402

pytestmark = pytest.mark.ros

FPS = 10  # the simulator encodes 1920x1080 in this process: few pictures a second keep the test light


@pytest.fixture(scope="module")
def sim() -> Iterator[SimulatedCamera]:
    cam = SimulatedCamera(model="q6075", https=False, auth="digest", password=PASSWORD).start()
    try:
        yield cam
    finally:
        cam.stop()


@pytest.fixture
def camera(sim: SimulatedCamera) -> SimulatedCamera:
    wait_until(lambda: not sim.rebooting, 10.0, 0.05, scaled=False, raises=False)
    return sim


@pytest.fixture
def cred(tmp_path: Path) -> str:
    path = tmp_path / "cred"
    path.write_text(f"root:{PASSWORD}\n", encoding="utf-8")
    return str(path)


class ParamsLog:
    """What ``video/params`` said, in order."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.msgs: list[VideoParams] = []

    def on_msg(self, msg: VideoParams) -> None:
        with self.lock:
            self.msgs.append(msg)

    def last(self) -> VideoParams | None:
        with self.lock:
            return self.msgs[-1] if self.msgs else None


def start(ros: RosHarness, camera: SimulatedCamera, cred: str, kbps: int):  # noqa: ANN201
    node = make_node(ros, camera, cred, resolution="", fps=FPS, h264_bitrate_kbps=kbps, h264_max_bitrate_kbps=kbps)
    probe = ros.probe()
    params = ParamsLog()
    probe.create_subscription(VideoParams, "video/params", params.on_msg, LATCHED_QOS)
    rec, _ = subscribe(probe)
    ros.wait_for(lambda: rec.count() >= 5, timeout=20)
    return node, probe, params, rec


def session_size(camera: SimulatedCamera) -> tuple[int, int]:
    assert camera.rtsp is not None
    (session,) = camera.rtsp.sessions
    return session.request.width, session.request.height


@pytest.mark.parametrize(
    ("kbps", "size"),
    [
        (2000, (1920, 1080)),  # 0.096 bit/px at 1080p: the largest the camera lists
        (100, (640, 360)),  # 1080p would get 0.005 bit/px; 640x360 0.043, 800x450 0.028 (under 0.03)
    ],
)
def test_auto_resolution_asks_the_camera_for_the_size_the_bitrate_reads_best_at(
    ros: RosHarness, camera: SimulatedCamera, cred: str, kbps: int, size: tuple[int, int]
) -> None:
    node, _probe, params, rec = start(ros, camera, cred, kbps)
    assert session_size(camera) == size
    assert camera.rtsp is not None
    assert camera.rtsp.sessions[0].request.bitrate_kbps == kbps
    assert bits_per_pixel(kbps, Resolution(*size), FPS) >= MIN_BITS_PER_PIXEL
    # the pictures are that size, and video/params says so (the camera's whole list still offered)
    assert {(p.width, p.height) for p in rec.since(0.0)} == {size}
    msg = ros.wait_for(lambda: (m := params.last()) is not None and (m.width, m.height) == size and m)
    assert msg.resolution == f"{size[0]}x{size[1]}"
    assert "1920x1080" in msg.available_resolutions
    assert node.live_params.params["resolution"] == ""  # the parameter stays auto


def test_a_lasting_bitrate_drop_restarts_the_camera_at_a_smaller_size(
    ros: RosHarness, camera: SimulatedCamera, cred: str
) -> None:
    node, probe, params, rec = start(ros, camera, cred, 2000)
    assert session_size(camera) == (1920, 1080)
    sizer = node._pipeline.size  # noqa: SLF001
    sizer.config = SizeConfig(down_hold_s=0.5, min_interval_s=1.0)  # the test's patience, not 2 s / 10 s
    assert all(r.successful for r in set_params(ros, probe, h264_bitrate_kbps=100, h264_max_bitrate_kbps=100))
    assert camera.rtsp is not None
    ros.wait_for(lambda: [s.request.width for s in camera.rtsp.sessions] == [640], timeout=15)
    assert sizer.changes == 1
    msg = ros.wait_for(lambda: (m := params.last()) is not None and m.width == 640 and m, timeout=5)
    assert (msg.resolution, msg.source) == ("640x360", "bandwidth_budget")
    n = rec.count()
    ros.wait_for(lambda: rec.count() >= n + 5, timeout=10)
    assert {(p.width, p.height) for p in rec.since(0.0)[-3:]} == {(640, 360)}


def test_an_explicit_resolution_is_asked_for_as_it_is(ros: RosHarness, camera: SimulatedCamera, cred: str) -> None:
    make_node(ros, camera, cred, resolution="1280x720", fps=FPS, h264_bitrate_kbps=100, h264_max_bitrate_kbps=100)
    rec, _ = subscribe(ros.probe())
    ros.wait_for(lambda: rec.count() >= 5, timeout=20)
    assert session_size(camera) == (1280, 720)  # 0.011 bit/px, but asked for
