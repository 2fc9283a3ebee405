"""A misconfigured port (issue 10): pointing the client's replies at a real, endless MJPEG stream of the
simulator gives a clear error at once, no memory growth and no thread left blocked."""

from __future__ import annotations

import threading
import time

import pytest

from axis_ptz_ros2.sim import SimulatedCamera
from axis_ptz_ros2.vapix import CameraConfig, ResponseParseError, VapixClient
from tests.support.waiting import wait_until

pytestmark = pytest.mark.integration


def test_reply_that_is_a_video_stream_is_refused_quickly():
    with (
        SimulatedCamera() as cam,
        VapixClient(CameraConfig(cam.host, cam.port, timeout_s=3.0)) as vapix,
    ):
        before = threading.active_count()
        t0 = time.monotonic()
        with pytest.raises(ResponseParseError, match="stream"):
            vapix._get_text("/axis-cgi/mjpg/video.cgi?resolution=176x144&fps=30")  # noqa: SLF001 - the wrong port
        assert time.monotonic() - t0 < 3.0
        # The same client still works for real replies afterwards (the stream's connection was closed).
        assert vapix.query_position().zoom == 1
        wait_until(
            lambda: not cam.request_counts.endpoints.get("video", 0) or threading.active_count() <= before + 1,
            5.0,
            0.05,
            scaled=False,
            raises=False,
        )
        assert threading.active_count() <= before + 1
