"""The simulator agrees with recorded real Axis replies and with itself (issue 10): MJPEG reply headers,
no foreign Server header, the PTZ parameter keys of real listings, query=limits == PTZ.Limit.L1, info=1
advertises only what ptz.cgi accepts, query=mode answered."""

from __future__ import annotations

import socket

import httpx
import pytest

from axis_ptz_ros2.sim import SimulatedCamera
from axis_ptz_ros2.vapix import CameraConfig, PtzLimits, VapixClient

pytestmark = pytest.mark.integration
MODELS = ["axis214", "q6075"]


@pytest.fixture(scope="module", params=MODELS)
def cam(request):
    with SimulatedCamera(model=request.param, auth="none", https=False) as c:
        yield c


@pytest.fixture
def http(cam):
    with httpx.Client(base_url=cam.base_url, timeout=5.0) as c:
        yield c


def _raw_head(cam: SimulatedCamera, target: str) -> list[str]:
    with socket.create_connection((cam.host, cam.port), timeout=5.0) as s:
        s.sendall(f"GET {target} HTTP/1.1\r\nHost: cam\r\n\r\n".encode())
        data = b""
        while b"\r\n\r\n" not in data:
            chunk = s.recv(4096)
            if not chunk:
                break
            data += chunk
    return data.split(b"\r\n\r\n", 1)[0].decode("latin-1").split("\r\n")


def test_mjpeg_reply_head_like_a_real_axis(cam):
    head = _raw_head(
        cam, "/axis-cgi/mjpg/video.cgi?resolution=" + ("176x144" if cam.persona.key == "axis214" else "640x360")
    )
    assert head[0] == "HTTP/1.0 200 OK"
    names = {line.split(":", 1)[0].lower(): line.split(":", 1)[1].strip() for line in head[1:]}
    assert "server" not in names
    assert "date" not in names
    assert names["expires"]
    assert names["content-type"] == "multipart/x-mixed-replace; boundary=myboundary"


def test_no_boa_server_header(cam, http):
    r = http.get("/axis-cgi/com/ptz.cgi?query=position")
    assert "boa" not in r.headers.get("server", "").lower()
    if cam.persona.key == "axis214":
        assert "server" not in r.headers


def test_ptz_group_has_the_keys_of_real_listings(http):
    listing = http.get("/axis-cgi/param.cgi?action=list&group=PTZ").text
    keys = {line.split("=", 1)[0] for line in listing.splitlines() if "=" in line}
    for key in (
        "PTZ.ImageSource.I0.PTZEnabled",
        "PTZ.Preset.P0.HomePosition",
        "PTZ.Preset.P0.Position.P1.Name",
        "PTZ.Preset.P0.Position.P1.Data",
        "PTZ.Limit.L1.MinBrightness",
        "PTZ.Limit.L1.MaxBrightness",
        "PTZ.Various.V1.AutoFocus",
        "PTZ.PTZDriverStatuses.Driver1Status",
        "PTZ.UserCtlQueue.U0.UserGroup",
        "PTZ.UserCtlQueue.U2.TimeoutType",
    ):
        assert key in keys, key


def test_query_limits_agrees_with_the_parameter_list(http):
    limits = dict(line.split("=", 1) for line in http.get("/axis-cgi/com/ptz.cgi?query=limits").text.split())
    listing = http.get("/axis-cgi/param.cgi?action=list&group=PTZ.Limit").text
    params = dict(line.split("=", 1) for line in listing.split())
    for name, value in limits.items():
        assert float(params[f"PTZ.Limit.L1.{name}"]) == float(value), name


def test_client_reads_the_same_limits_both_ways(cam):
    with VapixClient(CameraConfig(cam.host, cam.port)) as vapix:
        via_query = vapix.query_limits()
        via_params = PtzLimits.from_params(vapix.list_params("PTZ.Limit"), camera=1)
    assert via_query == via_params


def test_info_advertises_only_accepted_commands(http):
    info = http.get("/axis-cgi/com/ptz.cgi?info=1").text
    assert "auxiliary=" not in info
    support = http.get("/axis-cgi/param.cgi?action=list&group=PTZ.Support.S1.Auxiliary").text
    assert support.strip().endswith("=false")
    assert http.get("/axis-cgi/com/ptz.cgi?auxiliary=wiper").text.startswith("Error")


def test_query_mode_answered(http):
    assert http.get("/axis-cgi/com/ptz.cgi?query=mode").text == "mode=normal\n"
