"""RtspReader against servers that misbehave at the socket level (no RTSP server needed): bounded, typed, no secrets."""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Iterator

import pytest

from axis_ptz_ros2.vapix.errors import AxisPtzError, CameraUnreachable
from axis_ptz_ros2.vapix.rtsp import MediaStreamRequest
from tests.support.pyav_rtsp import RtspReader

pytestmark = pytest.mark.integration

PASSWORD = "pw-never-shown"


@pytest.fixture
def silent_port() -> Iterator[int]:
    """A loopback port that accepts connections and never says a word."""
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(4)
    held: list[socket.socket] = []
    stop = threading.Event()

    def accept() -> None:
        srv.settimeout(0.2)
        while not stop.is_set():
            try:
                held.append(srv.accept()[0])
            except TimeoutError:
                continue

    t = threading.Thread(target=accept, daemon=True)
    t.start()
    try:
        yield srv.getsockname()[1]
    finally:
        stop.set()
        t.join(timeout=2)
        for c in held:
            c.close()
        srv.close()


def test_silent_server_gives_a_typed_error_within_the_timeouts(silent_port: int) -> None:
    url = MediaStreamRequest().url("127.0.0.1", silent_port, "viewer", PASSWORD)
    t0 = time.monotonic()
    with pytest.raises(AxisPtzError) as info:
        RtspReader(url, open_timeout_s=3, read_timeout_s=2, secrets=(PASSWORD,)).open()
    assert time.monotonic() - t0 < 8
    assert PASSWORD not in str(info.value)
    assert "viewer" not in str(info.value)


def test_refused_connection_is_camera_unreachable() -> None:
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    with pytest.raises(CameraUnreachable) as info:
        RtspReader(MediaStreamRequest().url("127.0.0.1", port, "viewer", PASSWORD), secrets=(PASSWORD,)).open()
    assert PASSWORD not in str(info.value)
