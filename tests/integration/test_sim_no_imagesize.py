"""A camera whose firmware has no ``imagesize.cgi`` (it answers 404; issue 23 item 7), over real HTTP.

The simulated 214 with ``no_imagesize``: our client still learns the camera's resolutions (from the video
standard the camera reports), never an empty list, and a snapshot at a learned size comes back at that size.
"""

from __future__ import annotations

import httpx
import pytest

from axis_ptz_ros2.sim import SimulatedCamera
from axis_ptz_ros2.sim.cli import build_parser
from axis_ptz_ros2.sim.faults import FaultConfig
from axis_ptz_ros2.sim.persona import RESOLUTIONS
from axis_ptz_ros2.streaming.jpeg import jpeg_size
from axis_ptz_ros2.vapix import CameraConfig, Resolution, VapixClient, VideoParams

pytestmark = pytest.mark.integration


@pytest.fixture(scope="module")
def cam():
    with SimulatedCamera(faults=FaultConfig(no_imagesize=True)) as c:
        yield c


def client(cam: SimulatedCamera) -> VapixClient:
    return VapixClient(CameraConfig(host="127.0.0.1", port=cam.port))


def test_the_simulated_camera_answers_imagesize_with_404(cam):
    with httpx.Client(base_url=cam.base_url, timeout=5.0) as http:
        for path in ("/axis-cgi/imagesize.cgi", "/axis-cgi/view/imagesize.cgi?resolution=CIF"):
            r = http.get(path)
            assert r.status_code == 404, path
            assert "404 Not Found" in r.text
        assert http.get("/axis-cgi/view/param.cgi?action=list&group=Brand").status_code == 200  # the rest answers


def test_the_client_learns_the_resolutions_without_imagesize(cam):
    with client(cam) as vapix:
        info = vapix.device_info()
        assert info.resolutions == tuple(Resolution(w, h) for w, h in dict.fromkeys(RESOLUTIONS.values()))
        assert vapix.resolution_problem == ""
        assert vapix.supported_resolutions() == info.resolutions
        # the learned size is what the camera streams
        jpeg = vapix.snapshot(VideoParams(resolution=Resolution(352, 288), fps=5, compression=30))
        assert jpeg_size(jpeg) == (352, 288)


def test_without_the_fault_imagesize_answers_as_before():
    with SimulatedCamera() as c, httpx.Client(base_url=c.base_url, timeout=5.0) as http:
        r = http.get("/axis-cgi/view/imagesize.cgi?resolution=CIF&squarepixel=0")
        assert r.status_code == 200
        assert "image width = 352" in r.text


def test_the_fault_from_the_command_line_and_the_control_endpoint(cam):
    assert build_parser().parse_args(["--fault-no-imagesize"]).fault_no_imagesize is True
    with SimulatedCamera() as c, httpx.Client(base_url=c.base_url, timeout=5.0) as http:
        assert http.get("/sim/control?no_imagesize=1").status_code == 200
        assert http.get("/axis-cgi/imagesize.cgi").status_code == 404
