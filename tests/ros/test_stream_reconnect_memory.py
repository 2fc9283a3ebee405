"""axis_stream keeps nothing per reconnect (issue 25's soak: RSS slope <= 1 MB/h with a camera reboot a minute).

The creep the soak found (~0.35 MB of RSS per reconnect, in the reader thread's malloc arena, invisible to
tracemalloc and to ``gc``) was an SSL context built for every MJPEG connection: httpx parses the CA bundle into
OpenSSL for each client it is not handed a context, and freeing it did not give the memory back. What the RSS
cannot show in a short test, the count can: after the first stream, reconnecting builds no SSL context at all.
Against the simulator over real DDS/HTTP; conditions are awaited, nothing is timed.
"""

from __future__ import annotations

import ssl
import threading
from collections.abc import Iterator
from typing import Any

import pytest

pytest.importorskip("rclpy")

from sensor_msgs.msg import CompressedImage  # noqa: E402

from axis_ptz_ros2.nodes.common import STREAM_QOS  # noqa: E402
from axis_ptz_ros2.sim import SimulatedCamera  # noqa: E402
from tests.support.harness import RosHarness  # noqa: E402
from tests.support.stream_node import make_stream_node  # noqa: E402

pytestmark = pytest.mark.ros

REBOOTS = 4


@pytest.fixture
def camera() -> Iterator[SimulatedCamera]:
    cam = SimulatedCamera(host="127.0.0.1", port=0).start()
    try:
        yield cam
    finally:
        cam.stop()


class ContextCount:
    """Counts the SSL contexts this process builds (``ssl.SSLContext.__new__``), by thread name."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        self.by_thread: list[str] = []
        self._lock = threading.Lock()
        original = ssl.SSLContext.__new__

        def counting_new(cls: type[ssl.SSLContext], *args: Any, **kwargs: Any) -> ssl.SSLContext:
            with self._lock:
                self.by_thread.append(threading.current_thread().name)
            return original(cls, *args, **kwargs)

        monkeypatch.setattr(ssl.SSLContext, "__new__", counting_new)


def test_reconnects_build_no_ssl_context(
    ros: RosHarness, camera: SimulatedCamera, monkeypatch: pytest.MonkeyPatch
) -> None:
    counted = ContextCount(monkeypatch)
    node = make_stream_node(ros, camera, fps=30, resolution="704x576")
    frames = [0]
    probe = ros.probe()
    probe.create_subscription(
        CompressedImage, "image_raw/compressed", lambda _m: frames.__setitem__(0, frames[0] + 1), STREAM_QOS
    )
    ros.wait_for(lambda: frames[0] >= 5, timeout=15)
    reader = node._reader  # noqa: SLF001
    connects = reader.stats().connects
    before = len(counted.by_thread)
    for _ in range(REBOOTS):
        camera.reboot(0.3)
        ros.wait_for(lambda: not camera.rebooting, timeout=5)
        ros.wait_for(lambda c=connects: reader.stats().connects > c, timeout=10)  # streaming again
        connects = reader.stats().connects
        seen = frames[0]
        ros.wait_for(lambda s=seen: frames[0] > s, timeout=5)  # and delivering
    built = counted.by_thread[before:]
    assert reader.stats().connects >= REBOOTS + 1
    assert built == [], f"{len(built)} SSL contexts built over {REBOOTS} reconnects (threads: {sorted(set(built))})"
