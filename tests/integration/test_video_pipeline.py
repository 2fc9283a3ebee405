"""The ROS-free video pipeline (``streaming/pipeline.py``) against the simulated cameras: frames come up through its
one callback, decisions go down to the H.264 side without the RTSP source or the stage asking the controller per
access unit (issue 38 item 1)."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from dataclasses import replace

import pytest

from axis_ptz_ros2.media.frame import H264, JPEG, EncodedFrame
from axis_ptz_ros2.media.h264_settings import H264Settings
from axis_ptz_ros2.sim.camera import SimulatedCamera
from axis_ptz_ros2.streaming.pipeline import Outlet, VideoPipeline
from axis_ptz_ros2.streaming.reader import ReaderConfig
from axis_ptz_ros2.streaming.status import LogLine
from axis_ptz_ros2.streaming.video_types import VideoSettings
from axis_ptz_ros2.vapix import CameraConfig, VapixClient
from tests.support.waiting import wait_until

pytest.importorskip("av")
pytestmark = pytest.mark.integration


class Out:
    """What the pipeline hands out and says."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.frames: list[tuple[EncodedFrame, Outlet]] = []
        self.params = 0
        self.lines: list[LogLine] = []

    def on_frame(self, frame: EncodedFrame, outlets: Outlet) -> None:
        with self.lock:
            self.frames.append((frame, outlets))

    def on_params(self) -> None:
        self.params += 1

    def of(self, codec: str) -> list[tuple[EncodedFrame, Outlet]]:
        with self.lock:
            return [(f, o) for f, o in self.frames if f.codec == codec]


def _pipeline(cam: SimulatedCamera, settings: VideoSettings, out: Out) -> VideoPipeline:
    client = VapixClient(CameraConfig(host="127.0.0.1", port=cam.port, timeout_s=3.0))
    return VideoPipeline(
        client,
        settings,
        ReaderConfig(),
        camera=1,
        model_file="",
        rtsp_port=cam.rtsp.port if cam.rtsp is not None else 554,
        lazy=True,
        on_frame=out.on_frame,
        on_params=out.on_params,
        on_profile=lambda _profile, _first: None,
        log=out.lines.append,
    )


@pytest.fixture
def running() -> Iterator[list[VideoPipeline]]:
    made: list[VideoPipeline] = []
    yield made
    for p in made:
        p.stop(1.5)


def test_jpegs_come_up_with_their_outlets_and_size(running: list[VideoPipeline]) -> None:
    cam = SimulatedCamera(rtsp_port=None).start()
    try:
        out = Out()
        p = _pipeline(cam, VideoSettings(fps=10, resolution="352x288"), out)
        running.append(p)
        p.start()
        assert not p.set_demand(0, 0, 0, frozenset)  # lazy: nobody asked, the reader stays off
        assert p.set_demand(1, 1, 0, frozenset)
        wait_until(lambda: len(out.of(JPEG)) >= 3, 10.0)
        frame, outlets = out.of(JPEG)[-1]
        assert outlets == Outlet.IMAGE | Outlet.CAMERA_INFO
        assert (frame.width, frame.height, frame.keyframe) == (352, 288, True)
        assert frame.data[:2] == b"\xff\xd8"
        assert frame.stamp_ns > 0
        assert not p.set_demand(0, 0, 0, frozenset)  # the last subscriber left: the reader stops
    finally:
        cam.stop()


def test_passed_through_h264_is_decided_once_not_per_access_unit(running: list[VideoPipeline]) -> None:
    cam = SimulatedCamera(model="q6075", https=False, auth="none").start()
    try:
        out = Out()
        settings = VideoSettings(
            fps=10, resolution="", codec="h264", h264=H264Settings(bitrate_kbps=400, max_bitrate_kbps=400)
        )
        p = _pipeline(cam, settings, out)
        running.append(p)
        calls = [0]
        decide = p.video.h264_settings

        def counted() -> object:
            calls[0] += 1
            return decide()

        p.video.h264_settings = counted  # type: ignore[method-assign]
        p.start()
        viewers = frozenset({"/viewer"})
        p.set_demand(0, 0, 1, lambda: viewers)
        wait_until(lambda: p.rtsp.supported is True and p.starts.subscribers == 1, 10.0)
        p.set_demand(0, 0, 1, lambda: viewers)  # (the node's 1 Hz poll)
        wait_until(lambda: len(out.of(H264)) >= 20, 20.0)
        asked = calls[0]
        wait_until(lambda: len(out.of(H264)) >= 40, 20.0)
        assert calls[0] == asked, "the H.264 side asked the controller per access unit"
        assert {o for _, o in out.of(H264)} == {Outlet.H264}
        assert out.of(H264)[0][0].keyframe  # a start point first
        # auto resolution, 400 kbit/s at 10 fps: the largest 16:9 size with 0.03 bit per pixel (640x360)
        state = p.video.state()
        assert p.size.size is not None
        assert state.params.resolution == p.size.size
        playing = cam.rtsp.sessions if cam.rtsp is not None else []
        assert any(s.request.width == p.size.size.width for s in playing)
        # a decision flows down at once: a new bitrate reaches the request the RTSP source reads, no frame needed
        h264 = H264Settings(bitrate_kbps=800, max_bitrate_kbps=800)
        p.apply(replace(settings, h264=h264), {"h264_bitrate_kbps"}, "t", True)
        assert p.rtsp._request().max_bitrate_kbps == 800  # noqa: SLF001 - the request it reads is the point
        assert p.h264_settings().bitrate_kbps == 800
    finally:
        cam.stop()
