"""The simulator's reboot that drops packets (issue 10): connects hang instead of being refused, open
connections go mute (no FIN), then the web server answers errors (503 / empty / 401) before video works;
the stream reader heals through all of it and publishes no old frame."""

from __future__ import annotations

import socket
import threading
import time

import httpx
import pytest

from axis_ptz_ros2.sim import SimulatedCamera
from axis_ptz_ros2.streaming import ReaderConfig, StreamReader
from axis_ptz_ros2.vapix import CameraConfig, Resolution, VapixClient, VideoParams
from tests.support.stamps import sim_stamp
from tests.support.waiting import wait_until

pytestmark = pytest.mark.integration
VIDEO = "/axis-cgi/mjpg/video.cgi?resolution=176x144&fps=10"


def _wait(pred, timeout: float) -> None:
    wait_until(pred, timeout, scaled=False)


def test_blackhole_connects_hang_and_open_streams_go_mute():
    # Long phases (4 s mute, 3 s errors) so that each step below fits in its phase on a loaded machine: the mute
    # phase holds the 0.3 s drain and the 0.5 s connect probe, the error phase two requests.
    with SimulatedCamera() as cam:
        stream = socket.create_connection((cam.host, cam.port), timeout=5.0)
        stream.sendall(f"GET {VIDEO} HTTP/1.1\r\nHost: x\r\n\r\n".encode())
        assert stream.recv(4096).startswith(b"HTTP/1.")
        cam.reboot(4.0, blackhole=True, errors_s=3.0, error_kind="503")
        assert cam.rebooting
        # the open stream: whatever was in flight, then silence, never an end of stream
        stream.settimeout(0.3)

        def drain() -> None:
            deadline = time.monotonic() + 10.0  # a stream still flowing after this is the failure, not a hang
            while stream.recv(65536):
                assert time.monotonic() < deadline, "the open stream kept sending through the blackhole"

        with pytest.raises(TimeoutError):
            drain()
        # a new connection: no refusal, the SYN is dropped and connect times out
        assert cam.rebooting
        assert not cam.serving_errors()
        probe = socket.socket()
        probe.settimeout(0.5)
        t0 = time.monotonic()
        with pytest.raises(TimeoutError):
            probe.connect((cam.host, cam.port))
        assert time.monotonic() - t0 >= 0.45
        probe.close()
        # back: errors first, then video
        _wait(lambda: cam.serving_errors(), 15.0)
        r = httpx.get(f"{cam.base_url}/axis-cgi/com/ptz.cgi?query=position", timeout=2.0)
        assert r.status_code == 503
        state = httpx.get(f"{cam.base_url}/sim/state", timeout=2.0).json()
        assert state["serving_errors"]
        assert state["video_ok_at"] > time.time()
        _wait(lambda: not cam.rebooting, 15.0)
        assert time.time() >= state["video_ok_at"]
        assert httpx.get(f"{cam.base_url}/axis-cgi/com/ptz.cgi?query=position", timeout=2.0).status_code == 200
        # the muted connection is reset once the camera is back (it knows nothing of it)
        stream.settimeout(2.0)
        with pytest.raises(ConnectionResetError):
            stream.recv(10)
        stream.close()


@pytest.mark.parametrize("kind", ["empty", "401"])
def test_reboot_error_kinds(kind):
    with SimulatedCamera(auth="digest") as cam:
        cam.reboot(0.1, errors_s=1.5, error_kind=kind)
        _wait(lambda: cam.serving_errors(), 5.0)
        if kind == "empty":
            with pytest.raises(httpx.RemoteProtocolError):
                httpx.get(f"{cam.base_url}/axis-cgi/com/ptz.cgi?query=position", timeout=2.0)
        else:
            r = httpx.get(
                f"{cam.base_url}/axis-cgi/com/ptz.cgi?query=position",
                timeout=2.0,
                auth=httpx.DigestAuth("root", "pass"),
            )
            assert r.status_code == 401
            assert r.headers["www-authenticate"].startswith("Digest ")


def test_reboot_options_over_sim_control():
    with SimulatedCamera() as cam:
        bad = httpx.get(f"{cam.base_url}/sim/control?reboot=1&reboot_error=418", timeout=2.0)
        assert bad.status_code == 400
        ok = httpx.get(
            f"{cam.base_url}/sim/control?reboot=0.5&reboot_blackhole=1&reboot_errors_s=0.5&reboot_error=empty",
            timeout=2.0,
        )
        assert ok.status_code == 200
        _wait(lambda: cam.rebooting, 2.0)
        _wait(lambda: cam.serving_errors(), 5.0)
        assert cam._error_kind == "empty"  # noqa: SLF001
        _wait(lambda: not cam.rebooting, 5.0)


def test_reader_heals_through_a_blackhole_reboot_without_republishing():
    with (
        SimulatedCamera() as cam,
        VapixClient(CameraConfig(cam.host, cam.port, connect_timeout_s=0.5, timeout_s=2.0)) as vapix,
    ):
        lock = threading.Lock()
        got: list[tuple[float, int]] = []

        def on_frame(jpeg: bytes, arrival_ns: int) -> None:
            st = sim_stamp(jpeg)
            with lock:
                got.append((time.time(), st[1] if st else -1))

        reader = StreamReader(
            vapix.open_mjpeg,
            on_frame,
            VideoParams(Resolution(176, 144), 10, 50),
            ReaderConfig(backoff_initial_s=0.05, backoff_max_s=0.5, stall_timeout_s=0.5, auth_retry_s=30.0),
        )
        reader.start()
        try:
            _wait(lambda: len(got) >= 3, 10.0)
            cam.reboot(2.0, blackhole=True, errors_s=1.0, error_kind="503")
            _wait(lambda: not cam.rebooting, 10.0)
            ok_at = cam.video_ok_at
            assert ok_at is not None
            _wait(lambda: any(t >= ok_at for t, _ in got), 10.0)
            stats = reader.stats()
            assert stats.reconnects >= 2
            assert stats.stalls >= 1  # the mute stream was caught by the read timeout, not by an EOF
            with lock:
                stamps = [s for _, s in got if s > 0]
            assert all(b > a for a, b in zip(stamps, stamps[1:], strict=False)), "an old frame was republished"
        finally:
            assert reader.stop(3.0)
