"""Every injectable fault of the simulated camera is observable on the wire (raw httpx)."""

import contextlib
import json
import time

import httpx
import pytest

from axis_ptz_ros2.sim import FaultConfig, SimulatedCamera
from tests.support.sim import COM, PART_HEADER, parts, read_stream
from tests.support.waiting import wait_until

pytestmark = pytest.mark.integration
VIDEO = "/axis-cgi/mjpg/video.cgi?resolution=CIF&fps=30"


@pytest.fixture
def client(cam):
    cam.set_faults(FaultConfig())
    with httpx.Client(base_url=cam.base_url, timeout=5.0) as c:
        yield c
    cam.set_faults(FaultConfig())


def test_drop_after_frames_closes_mid_part(cam, client):
    cam.set_faults(drop_after_frames=3)
    _, _, body, _ = read_stream(client, VIDEO, max_seconds=3)
    ps = parts(body)
    assert len(ps) == 4  # three complete parts, then the headers of a fourth
    length, start = ps[-1]
    assert len(body) - start < length  # cut mid-JPEG, then EOF


def test_stall_keeps_socket_open_then_resumes(cam, client):
    cam.set_faults(stall_after_frames=2, stall_seconds=0.8)
    _, _, body, marks = read_stream(client, VIDEO + "&nbrofframes=4", max_seconds=4)
    ps = parts(body)
    assert len(ps) == 4
    # the camera's own send stamps (not arrival times, which a loaded client shifts): the one long gap is the
    # configured stall, after the second frame; it lasts at least stall_seconds
    sent_ns = [int(m.group(2)) for m in COM.finditer(body)]
    assert len(sent_ns) == 4
    gaps = [(b - a) / 1e9 for a, b in zip(sent_ns, sent_ns[1:], strict=False)]
    assert gaps[1] >= 0.8 - 0.01, gaps
    assert max(gaps) == gaps[1], gaps


def test_garbage_between_parts(cam, client):
    cam.set_faults(garbage_between_parts=True)
    _, _, body, _ = read_stream(client, VIDEO + "&nbrofframes=3", max_seconds=3)
    ps = parts(body)
    length, start = ps[0]
    nxt = PART_HEADER.search(body, start + length).start()
    assert nxt - (start + length) > 2  # more than the CRLF


def test_truncated_jpeg_every_nth(cam, client):
    cam.set_faults(truncate_every=2)
    _, _, body, _ = read_stream(client, VIDEO + "&nbrofframes=4", max_seconds=3)
    ends = [body[s + n - 2 : s + n] for n, s in parts(body)]
    assert ends[0] == b"\xff\xd9"
    assert ends[1] != b"\xff\xd9"
    assert ends[2] == b"\xff\xd9"
    assert ends[3] != b"\xff\xd9"


def test_wrong_content_length(cam, client):
    cam.set_faults(wrong_length_every=2, wrong_length_delta=100)
    _, _, body, _ = read_stream(client, VIDEO + "&nbrofframes=3", max_seconds=3)
    ps = parts(body)
    actual = [ps[i + 1][1] - len(PART_HEADER.search(body, ps[i][1]).group(0)) - 2 - ps[i][1] for i in range(2)]
    assert actual[0] == ps[0][0]
    assert ps[1][0] == actual[1] + 100


@pytest.mark.parametrize("code", [401, 500, 503])
def test_http_error_on_video_only(cam, client, code):
    cam.set_faults(http_error=code, http_error_scope="video")
    assert client.get(VIDEO).status_code == code
    assert client.get("/axis-cgi/jpg/image.cgi").status_code == code
    assert client.get("/axis-cgi/com/ptz.cgi", params={"query": "speed"}).status_code == 200


def test_http_error_on_all(cam, client):
    cam.set_faults(http_error=500)
    assert client.get("/axis-cgi/com/ptz.cgi", params={"query": "speed"}).status_code == 500
    assert client.get("/sim/state").status_code == 200  # control endpoints are never faulted


def test_added_latency(cam, client):
    cam.set_faults(latency_ms=300)
    t0 = time.monotonic()
    assert client.get("/axis-cgi/com/ptz.cgi", params={"query": "speed"}).status_code == 200
    assert time.monotonic() - t0 >= 0.3


def test_bandwidth_cap(cam, client):
    cam.set_faults(bandwidth_kbps=800)  # 100 kB/s
    # The rate the camera sent at, from its own send stamps (one per part, taken as the part starts to go out):
    # a loaded client reads its socket backlog in bursts, so arrival times would inflate the rate. Parts of
    # ~64 kB: four stamps (three parts sent) take ~2 s.
    body = b""
    deadline = time.monotonic() + 30.0
    with client.stream("GET", "/axis-cgi/mjpg/video.cgi?resolution=CIF&compression=0&fps=0") as r:
        for chunk in r.iter_raw():
            body += chunk
            if len(COM.findall(body)) >= 4:
                break
            assert time.monotonic() < deadline, f"{len(COM.findall(body))} parts in 30 s"
    sent_ns = [int(m.group(2)) for m in COM.finditer(body)]
    starts = [m.start() for m in PART_HEADER.finditer(body)]
    assert len(sent_ns) >= 4
    # bytes of the parts between the first and the last stamp, over the time between the two stamps
    rate = (starts[len(sent_ns) - 1] - starts[0]) / ((sent_ns[-1] - sent_ns[0]) / 1e9)
    assert 50_000 < rate < 130_000, rate


def test_control_endpoint_sets_faults_and_reports_state(cam, client):
    r = client.get("/sim/control", params={"latency_ms": "5", "garbage_between_parts": "1", "teleport": "10,5,1000"})
    state = json.loads(r.text)
    assert state["faults"]["latency_ms"] == 5
    assert state["faults"]["garbage_between_parts"] is True
    assert (state["pan"], state["tilt"], state["zoom"]) == pytest.approx((10, 5, 1000))
    assert cam.faults.latency_ms == 5
    assert client.get("/sim/control", params={"nonsense": "1"}).status_code == 400
    client.get("/sim/control", params={"reset_faults": "1"})
    assert cam.faults == FaultConfig()


def test_reboot_refuses_then_recovers_on_same_port():
    with SimulatedCamera() as cam, httpx.Client(base_url=cam.base_url, timeout=3.0) as c:
        port = cam.port
        c.get("/axis-cgi/com/ptz.cgi", params={"pan": "30"})
        with c.stream("GET", VIDEO) as stream:
            it = stream.iter_raw()
            next(it)
            c.get("/sim/control", params={"reboot": "3.0"})
            t0 = time.monotonic()
            with contextlib.suppress(httpx.HTTPError):  # the open stream ends (EOF or reset)
                for _ in it:
                    if time.monotonic() - t0 > 20:
                        break
            assert time.monotonic() - t0 <= 20, "the open stream kept going through the reboot"
        # while the camera reboots (3 s: ample margin on a loaded machine) nothing is served, and once its
        # listening socket is gone connections are refused (until then a connection may be reset instead)
        refused = False

        def refused_or_back() -> bool:
            nonlocal refused
            if not cam.rebooting:
                return True
            try:
                r = httpx.get(cam.base_url + "/axis-cgi/com/ptz.cgi?query=speed", timeout=1.0)
            except httpx.ConnectError:
                refused = True
                return True
            except (httpx.ReadError, httpx.RemoteProtocolError, httpx.ReadTimeout):
                return False
            assert not cam.rebooting, f"served while rebooting: {r.status_code}"
            return True

        wait_until(refused_or_back, 60.0, 0.05, scaled=False)
        assert refused, "no connection was refused during the reboot"
        wait_until(lambda: not cam.rebooting, 15.0, 0.05, scaled=False, raises=False)
        assert not cam.rebooting
        assert cam.port == port
        r = httpx.get(cam.base_url + "/axis-cgi/com/ptz.cgi?query=position", timeout=2.0)
        assert r.text.startswith("pan=0\ntilt=0\nzoom=1\n")  # came back at home
        assert COM.match(httpx.get(cam.base_url + "/axis-cgi/jpg/image.cgi", timeout=2.0).content)
