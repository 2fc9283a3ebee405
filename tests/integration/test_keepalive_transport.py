"""The state poll's http.client transport (vapix/keepalive.py) keeps what VapixClient guarantees over httpx's own:
one kept-alive connection, Digest/Basic negotiation and re-challenge, timeouts against a black-holed camera,
recovery after a reboot, capped reads, typed errors without credentials, HTTPS (simulated camera, loopback)."""

from __future__ import annotations

import time

import pytest

from axis_ptz_ros2.sim.camera import SimulatedCamera
from axis_ptz_ros2.vapix import (
    AuthError,
    CameraConfig,
    CameraTimeout,
    CameraUnreachable,
    HttpStatusError,
    ResponseParseError,
    VapixClient,
)
from axis_ptz_ros2.vapix.keepalive import KeepAliveTransport
from tests.support.waiting import succeeds, wait_until

pytestmark = pytest.mark.integration


def _client(cam: SimulatedCamera, **kw) -> VapixClient:
    https = cam.base_url.startswith("https")
    config = CameraConfig(port=cam.port, use_https=https, verify_tls=not https, **kw)
    return VapixClient(config, transport=KeepAliveTransport(config.ssl_verify() if https else True))


def _socket(client: VapixClient):
    (connection,) = client._pool._idle  # noqa: SLF001 - which connection was used is the point
    return connection.conn.sock


@pytest.fixture
def sim():
    cam = SimulatedCamera().start()
    try:
        yield cam
    finally:
        cam.stop()


def test_polls_reuse_one_connection(sim):
    with _client(sim, timeout_s=2.0) as c:
        assert c.query_position().zoom == 1
        sock = _socket(c)
        for _ in range(20):
            c.query_position()
        assert _socket(c) is sock


@pytest.mark.parametrize("mode", ["digest", "basic_digest"])
def test_digest_negotiated_and_rechallenged_on_one_connection(mode):
    cam = SimulatedCamera(auth=mode, user="operator", password="s3cret-pw").start()
    try:
        with _client(cam, username="operator", password="s3cret-pw") as c:
            c.query_position()
            sock = _socket(c)
            cam.forget_nonces()  # the camera restarted its web server: the next signed request gets a 401
            c.query_position()
            assert c.auth_counters.rechallenges == 1
            assert _socket(c) is sock  # the 401 body was read, the connection kept
        with _client(cam, username="operator", password="wrong-pw") as c, pytest.raises(AuthError) as err:
            c.query_position()
        assert "wrong-pw" not in str(err.value)
    finally:
        cam.stop()


def test_https_digest_persona():
    cam = SimulatedCamera(model="q6075").start()
    try:
        assert cam.base_url.startswith("https://")
        with _client(cam, username="root", password="pass") as c:
            assert c.query_position().zoom >= 1
            sock = _socket(c)
            c.query_position()
            assert _socket(c) is sock
    finally:
        cam.stop()


def test_errors_reboot_and_recovery(sim):
    with _client(sim, timeout_s=2.0) as c:
        sim.set_faults(http_error=503)
        with pytest.raises(HttpStatusError):
            c.query_position()
        sim.set_faults(http_error=0)
        c.query_position()
        sim.reboot(0.5)
        with pytest.raises(CameraUnreachable):
            c.query_position()
        wait_until(
            succeeds(c.query_position, CameraUnreachable), 5.0, 0.1, scaled=False, what="recovery after the reboot"
        )


def test_black_holed_camera_times_out_then_recovers(sim):
    with _client(sim, timeout_s=0.5, connect_timeout_s=0.5) as c:
        c.query_position()
        sim.reboot(1.5, blackhole=True)
        t0 = time.monotonic()
        with pytest.raises((CameraTimeout, CameraUnreachable)):
            c.query_position()  # the kept connection went mute, or was replaced and the connect hangs
        with pytest.raises(CameraTimeout):
            c.query_position()  # a connect into the black hole
        assert time.monotonic() - t0 < 3.0
        wait_until(
            succeeds(c.query_position, CameraTimeout, CameraUnreachable),
            6.0,
            0.1,
            scaled=False,
            what="recovery after the black hole",
        )


def test_a_stream_is_refused_capped_and_the_next_request_works(sim):
    with _client(sim, timeout_s=2.0) as c:
        with pytest.raises(ResponseParseError):
            c._get("/axis-cgi/mjpg/video.cgi")  # noqa: SLF001 - the capped read of a stream
        assert c.query_position().zoom == 1
