"""streaming/discovery.py against the simulated camera: learn once, open the stream, probe an absent camera."""

from __future__ import annotations

import socket
import threading

import pytest

from axis_ptz_ros2.camera_models import CameraProfile
from axis_ptz_ros2.sim.camera import SimulatedCamera
from axis_ptz_ros2.streaming.discovery import CameraDiscovery, probe_tcp
from axis_ptz_ros2.vapix import CameraConfig, CameraUnreachable, Resolution, VapixClient, VideoParams
from tests.support.waiting import wait_until

pytestmark = pytest.mark.integration

P176 = VideoParams(Resolution(176, 144), 10, 50)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class Seen:
    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.profiles: list[tuple[str, bool]] = []
        self.lists: list[tuple[Resolution, ...]] = []
        self.problems: list[str] = []

    def discovery(self, client: VapixClient, **kw) -> CameraDiscovery:
        return CameraDiscovery(
            client,
            "",
            lambda: P176,
            on_profile=self.profile,
            on_resolutions=self.lists.append,
            on_problem=self.problems.append,
            **kw,
        )

    def profile(self, profile: CameraProfile, first: bool) -> None:
        with self.lock:
            self.profiles.append((profile.model.name, first))


def test_tcp_port_is_known_in_one_place():
    assert CameraConfig("h").tcp_port == 80
    assert CameraConfig("h", use_https=True).tcp_port == 443
    assert CameraConfig("h", port=8080, use_https=True).tcp_port == 8080


def test_probe_refuses_a_closed_port_with_host_and_port():
    port = _free_port()
    with pytest.raises(CameraUnreachable, match=f"127.0.0.1:{port} not accepting connections"):
        probe_tcp(CameraConfig("127.0.0.1", port, connect_timeout_s=0.5))


def test_learns_the_camera_once_at_start_up_and_opens_its_stream():
    seen = Seen()
    with SimulatedCamera() as cam, VapixClient(CameraConfig(cam.host, cam.port, timeout_s=3.0)) as client:
        d = seen.discovery(client)
        d.start()
        wait_until(lambda: d.learned, 10.0, 0.02, scaled=False, raises=False)
        d.stop(2.0)
        assert Resolution(704, 576) in d.learned
        assert seen.lists == [d.learned], "the list is handed over once"
        assert seen.profiles == [("AXIS 214 PTZ", True)]
        assert d.learn() == d.learned
        assert len(seen.profiles) == 1, "asked once"
        stream = d.open(P176, 2.0)
        try:
            frame = next(iter(stream))
            assert frame[:2] == b"\xff\xd8"
        finally:
            stream.close()
        assert not seen.problems


def test_an_absent_camera_is_probed_with_tcp_and_retried_with_back_off():
    seen = Seen()
    port = _free_port()
    with VapixClient(CameraConfig("127.0.0.1", port, connect_timeout_s=0.3, timeout_s=0.5)) as client:
        d = seen.discovery(client, first_delay_s=0.05, max_delay_s=0.1)
        with pytest.raises(CameraUnreachable) as first:
            d.open(P176, 0.5)
        assert "not accepting connections" not in str(first.value), "the first attempt is HTTP"
        with pytest.raises(CameraUnreachable, match="not accepting connections"):
            d.open(P176, 0.5)  # then a bare TCP connect decides
        d.start()
        wait_until(lambda: len(seen.problems) >= 3, 5.0, what="the start-up thread to keep asking")
        d.stop(2.0)
        assert len(seen.problems) >= 3, "the start-up thread keeps asking"
        assert all(p.startswith("cannot ask the camera what it is") for p in seen.problems)
        assert not d.learned
        assert not seen.profiles
