"""VAPIX conformance of the simulated Axis 214 over loopback HTTP, with raw httpx (no project client)."""

import re
import time

import numpy as np
import pytest

from axis_ptz_ros2.sim.frames import MAX_COMPRESSION
from tests.support.sim import blob, decode
from tests.support.waiting import wait_until

pytestmark = pytest.mark.integration
PTZ = "/axis-cgi/com/ptz.cgi"


def wait_still(cam, timeout=6.0):
    wait_until(lambda: not cam.state.moving(), timeout, 0.02, scaled=False, raises=False)


def query_position(client):
    r = client.get(PTZ, params={"query": "position"})
    assert r.status_code == 200
    assert r.headers["content-type"].startswith("text/plain")
    return dict(line.split("=", 1) for line in r.text.splitlines())


def test_commands_are_204_empty_and_position_has_sub_degree_precision(cam, client):
    r = client.get(PTZ, params={"pan": "12.3456", "tilt": "-7.25", "zoom": "2500"})
    assert r.status_code == 204
    assert r.content == b""
    wait_still(cam)
    pos = query_position(client)
    assert pos["pan"] == "12.3456"
    assert pos["tilt"] == "-7.25"
    assert pos["zoom"] == "2500"
    assert re.fullmatch(r"-?\d+(\.\d{1,4})?", pos["pan"])
    assert cam.position() == pytest.approx((12.3456, -7.25, 2500.0))
    assert {"iris", "focus", "autofocus", "autoiris"} <= set(pos)


def test_post_form_body_is_accepted(cam, client):
    r = client.post(PTZ, data={"pan": "-3", "tilt": "2"})
    assert r.status_code == 204
    wait_still(cam)
    assert cam.position()[:2] == pytest.approx((-3.0, 2.0))


@pytest.mark.parametrize(
    ("query", "message"),
    [
        ({"pan": "500"}, "pan: value out of range: 500"),
        ({"zoom": "0"}, "zoom: value out of range: 0"),
        ({"tilt": "abc"}, "tilt: invalid value: abc"),
        ({"query": "foo"}, "query: unknown value: foo"),
        ({"bogus": "1"}, "Unknown argument: bogus"),
        ({"pan": "10", "compression": "5"}, "Unknown argument: compression"),
    ],
)
def test_errors_are_200_error_text_and_change_nothing(cam, client, query, message):
    wait_still(cam)
    before = cam.position()
    r = client.get(PTZ, params=query)
    assert r.status_code == 200
    assert r.text == f"Error:\n{message}\n"
    time.sleep(0.05)  # a window for a (wrong) move: the thing under test is that the head stays put
    assert cam.position() == pytest.approx(before)


@pytest.mark.parametrize(
    ("compression", "status"), [(0, 200), (MAX_COMPRESSION, 200), (MAX_COMPRESSION + 1, 400), (-1, 400)]
)
def test_image_compression_runs_from_0_to_the_cameras_top(client, compression, status):
    r = client.get("/axis-cgi/jpg/image.cgi", params={"resolution": "176x144", "compression": compression})
    assert r.status_code == status
    if status == 400:
        assert r.text == f"Error:\nInvalid compression: {compression}\n"


def test_in_range_beyond_limits_is_clamped(cam, client):
    assert client.get(PTZ, params={"tilt": "-60", "pan": "175"}).status_code == 204
    wait_still(cam)
    pos = query_position(client)
    assert float(pos["tilt"]) == -30.0
    assert float(pos["pan"]) == 170.0


def test_dynamics_report_intermediate_positions(cam, client):
    # Times bracket each event (a loaded machine only widens the brackets): the move starts while the command
    # is in flight [t0, t1]; the position is read while the query is [t2, t3]; 100 deg/s, no acceleration.
    cam.teleport(-170, 0, 1)
    t0 = time.monotonic()
    client.get(PTZ, params={"pan": "170"})  # 340 deg at 100 deg/s = 3.4 s
    t1 = time.monotonic()
    wait_until(lambda: cam.position()[0] > -120.0, 10.0, what="the head under way")  # 50 deg of 340
    t2 = time.monotonic()
    pan = float(query_position(client)["pan"])
    t3 = time.monotonic()
    assert -170 < pan < 170
    assert 100 * (t2 - t1) - 0.01 <= pan + 170 <= 100 * (t3 - t0) + 0.01
    client.get(PTZ, params={"continuouspantiltmove": "-50,0"})  # cancels the absolute move: -50 deg/s
    ta = time.monotonic()  # the reply came after the simulator applied the command
    p1 = cam.position()[0]
    tb = time.monotonic()
    wait_until(lambda: cam.position()[0] < p1 - 15.0, 10.0, what="the head 15 deg further left")
    tc = time.monotonic()
    p2 = cam.position()[0]
    td = time.monotonic()
    assert 50 * (tc - tb) - 0.01 <= p1 - p2 <= 50 * (td - ta) + 0.01
    client.get(PTZ, params={"continuouspantiltmove": "0,0"})
    p2 = cam.position()[0]
    time.sleep(0.2)  # a window for a (wrong) drift: the thing under test is that the head stays put
    assert cam.position()[0] == pytest.approx(p2, abs=0.01)


def test_queries_info_presets_and_counts(cam, client):
    cam.reset_counts()
    lim = dict(line.split("=") for line in client.get(PTZ, params={"query": "limits"}).text.splitlines())
    assert lim["MinPan"] == "-170"
    assert lim["MaxTilt"] == "90"
    assert lim["MaxZoom"] == "9999"
    assert lim["MinFieldAngle"] == "27"
    assert lim["MaxFieldAngle"] == "480"
    assert client.get(PTZ, params={"query": "speed"}).text == "speed=100\n"
    assert client.get(PTZ, params={"info": "1"}).text.startswith("Available commands\n")
    assert client.get("/axis-cgi/com/ptzconfig.cgi", params={"setserverpresetname": "Gate"}).status_code == 204
    presets = client.get(PTZ, params={"query": "presetposall"}).text
    assert presets.startswith("Preset Positions for camera 1\npresetposno1=Home\n")
    assert "=Gate" in presets
    counts = cam.request_counts
    assert counts.endpoints["ptz"] == 4
    assert counts.endpoints["ptzconfig"] == 1
    assert counts.ptz["query=limits"] == 1
    assert [e.query for e in counts.ptz_log][:2] == ["query=limits", "query=speed"]


def test_param_cgi_persona_and_paths(client):
    r = client.get("/axis-cgi/view/param.cgi", params={"action": "list", "group": "root.Properties.API.HTTP.Version"})
    assert r.text == "root.Properties.API.HTTP.Version=2\n"
    body = client.get("/axis-cgi/admin/param.cgi", params={"action": "list", "group": "Brand,Properties"}).text
    assert "Brand.ProdShortName=AXIS 214 PTZ\n" in body
    assert "Properties.Image.Resolution=4CIF,2CIFEXP,2CIF,CIF,QCIF\n" in body
    assert "Properties.Firmware.Version=4.49\n" in body
    ptz = client.get("/axis-cgi/param.cgi", params={"action": "list", "group": "root.PTZ"}).text
    assert "root.PTZ.Limit.L1.MinTilt=-30\n" in ptz
    assert "root.PTZ.Support.S1.AbsolutePan=true\n" in ptz
    err = client.get("/axis-cgi/param.cgi", params={"action": "list", "group": "Nope"}).text
    assert err == "# Error: Error -1 getting param in group 'Nope'\n"
    assert client.get(
        "/axis-cgi/operator/param.cgi", params={"action": "update", "Brand.ProdNbr": "1"}
    ).text.startswith("# Error: Error setting")


def test_imagesize_videostatus_and_404(client):
    assert client.get("/axis-cgi/view/imagesize.cgi", params={"resolution": "QCIF", "squarepixel": "1"}).text == (
        "image width = 192\nimage height = 144\n"
    )
    assert client.get("/axis-cgi/imagesize.cgi").text == "image width = 704\nimage height = 576\n"
    assert client.get("/axis-cgi/view/videostatus.cgi", params={"status": "1"}).text == "Video 1 = video\n"
    r = client.get("/axis-cgi/apidiscovery.cgi")
    assert r.status_code == 404
    assert "The requested URL /axis-cgi/apidiscovery.cgi was not found on this server." in r.text


# Target colours (BGR ranges) of the high (tilt ~ +39 deg) and the ground (tilt ~ -24 deg) markers.
MAGENTA = ((200, 0, 200), (255, 90, 255))
ORANGE = ((0, 100, 200), (80, 180, 255))


@pytest.mark.parametrize(("name", "rng", "start"), [("high", MAGENTA, (8.0, 34.0)), ("ground", ORANGE, (22.5, -21.0))])
def test_center_on_rendered_target_at_steep_tilt(cam, client, name, rng, start):
    cam.teleport(start[0], start[1], 1)
    img = decode(client.get("/axis-cgi/jpg/image.cgi", params={"compression": "0"}).content)
    c0 = blob(img, *rng)
    assert c0 is not None
    assert np.hypot(c0[0] - 351.5, c0[1] - 287.5) > 40  # clearly off-centre before
    r = client.get(PTZ, params={"center": f"{c0[0]:.0f},{c0[1]:.0f}", "imagewidth": "704", "imageheight": "576"})
    assert r.status_code == 204
    wait_still(cam)
    img = decode(client.get("/axis-cgi/jpg/image.cgi", params={"compression": "0"}).content)
    c1 = blob(img, *rng)
    assert np.hypot(c1[0] - 351.5, c1[1] - 287.5) <= 3.0
