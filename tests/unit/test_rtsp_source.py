"""The pass-through reader (streaming/rtsp_source.py): request, reconnect policy, IDR on demand, no stale frame.

The session here is a scripted stand-in for a camera's RTSP session (the real one is exercised against the
simulator in tests/ros/test_stream_passthrough.py); the sink is the real H264Stage."""

from __future__ import annotations

import threading
import time
from collections import deque

import numpy as np

from axis_ptz_ros2.media import annexb
from axis_ptz_ros2.media.encoder import H264Encoder
from axis_ptz_ros2.media.frame import EncodedFrame
from axis_ptz_ros2.media.h264_settings import H264Settings
from axis_ptz_ros2.streaming.h264 import H264Stage
from axis_ptz_ros2.streaming.reader import ReaderConfig
from axis_ptz_ros2.streaming.rtsp_source import (
    RtspH264Source,
    media_request,
    needs_reconnect,
)
from axis_ptz_ros2.streaming.wall_clock import WallClockSteps
from axis_ptz_ros2.vapix.errors import CameraTimeout, CameraUnreachable
from axis_ptz_ros2.vapix.models import Resolution, VideoParams
from axis_ptz_ros2.vapix.rtsp import MediaStreamRequest, RtspStatusError
from axis_ptz_ros2.vapix.rtsp_rtp import RtpAccessUnit
from axis_ptz_ros2.vapix.rtsp_sdp import NoH264VideoError
from tests.support.waiting import wait_until


def test_media_request_follows_the_params_and_caps_the_gop_at_one_second() -> None:
    req = media_request(
        VideoParams(Resolution(1920, 1080), 30, 0),
        H264Settings(bitrate_kbps=800, max_bitrate_kbps=1500, keyframe_interval=300, fps=30),
    )
    assert req == MediaStreamRequest(resolution="1920x1080", fps=30, keyframe_interval=30, max_bitrate_kbps=800)
    q = dict(req.query())
    assert q["videozgopmode"] == "fixed"
    assert q["h264profile"] == "baseline"
    assert q["videobitratemode"] == "mbr"


def test_a_small_or_recent_bitrate_move_does_not_reconnect() -> None:
    a = MediaStreamRequest(max_bitrate_kbps=1000)
    assert not needs_reconnect(a, a, 100.0)
    assert not needs_reconnect(a, MediaStreamRequest(max_bitrate_kbps=1100), 100.0)
    assert not needs_reconnect(a, MediaStreamRequest(max_bitrate_kbps=500), 0.5)
    assert needs_reconnect(a, MediaStreamRequest(max_bitrate_kbps=500), 10.0)
    assert needs_reconnect(a, MediaStreamRequest(resolution="640x360", max_bitrate_kbps=1000), 0.0)


def _timing(*, read_timeout_s: float, stall_timeout_s: float) -> ReaderConfig:
    """Quick reconnects for a test."""
    return ReaderConfig(
        backoff_initial_s=0.01,
        backoff_max_s=0.05,
        auth_retry_s=1.0,
        read_timeout_s=read_timeout_s,
        stall_timeout_s=stall_timeout_s,
    )


def _stream(n: int) -> list[bytes]:
    enc = H264Encoder(
        H264Settings(
            fps=15, bitrate_kbps=200, keyframe_interval=100, preset="veryfast", profile="baseline", refresh="idr"
        ),
        64,
        48,
    )
    return [enc.encode_bgr(np.full((48, 64, 3), i * 7 % 255, np.uint8)).data for i in range(n)]


class Session:
    """A camera's playing session, scripted: access units, then an error."""

    def __init__(self, units: list[bytes], then: Exception, t0_ns: int) -> None:
        self.units = deque(units)
        self.then = then
        self.t0_ns = t0_ns
        self.renews = 0
        self.sent = 0
        self.adjusted: list[int | None] = []
        self.closed = threading.Event()

    def open(self) -> None:
        pass

    def close(self) -> None:
        self.closed.set()

    def read(self, timeout_s: float | None = None) -> RtpAccessUnit:
        if self.closed.is_set():
            raise CameraUnreachable("closed")
        if not self.units:
            self.closed.wait(timeout_s)
            raise self.then
        data = self.units.popleft()
        time.sleep(0.02)  # the scripted camera's frame pacing (50 access units a second)
        self.sent += 1
        return RtpAccessUnit(data, annexb.is_idr(data), 0, self.t0_ns + self.sent)

    def renew_stream(self) -> object:
        self.renews += 1
        return None

    def adjust_stream(self, *, fps: int | None = None, max_bitrate_kbps: int | None = None) -> object:
        self.adjusted.append(max_bitrate_kbps)
        return None


def test_plays_renews_reconnects_and_never_publishes_a_dead_sessions_frames() -> None:
    units = _stream(40)
    sessions = [Session(units, CameraTimeout("stall"), 1_000), Session(units[:5], CameraTimeout("stall"), 9_000)]
    made: list[Session] = []
    read_timeouts: list[float] = []
    out: list[EncodedFrame] = []
    stage = H264Stage(lambda: H264Settings(), out.append)
    stage.set_active(True)

    def connect(_req: MediaStreamRequest, read_timeout_s: float) -> Session:
        s = sessions[min(len(made), len(sessions) - 1)]
        made.append(s)
        read_timeouts.append(read_timeout_s)
        return s

    told: list[bool] = []
    timing = _timing(read_timeout_s=0.5, stall_timeout_s=0.1)
    src = RtspH264Source(
        connect,
        lambda: MediaStreamRequest(resolution="64x48", fps=15),
        stage,
        supports_h264=lambda: True,
        on_supported=told.append,
        config=timing,
    )
    src.start()
    try:
        src.set_active(True)
        wait_until(lambda: out, timeout=5, what="the first session's frames")
        stage.request_idr()  # a new subscriber: within the on-demand rate limit of the session's start, so held
        wait_until(lambda: len(made) >= 2, timeout=5, what="a reconnect after the stall")
        assert told == [True]
        wait_until(lambda: len(out) >= 45, timeout=5, raises=False)
    finally:
        src.stop()
    assert len(out) >= 45
    assert out[0].keyframe  # each session starts at its IDR
    assert out[40].keyframe
    assert [f.pts for f in out] == sorted({f.pts for f in out})
    assert all((f.width, f.height) == (64, 48) for f in out)
    assert out[40].stamp_ns > out[39].stamp_ns  # the second session's frames are newer than the dead one's
    assert made[0].renews == 1  # the held request, once the rate limit ended: one Renew-Stream
    assert made[1].renews == 0  # a new session starts with an IDR: no Renew-Stream for it
    assert src.stats.reconnects >= 1
    # the MJPEG reader's stall limit: 3 frame periods at 15 fps (0.2 s) over a shorter stall_timeout_s
    assert read_timeouts[0] == timing.read_timeout(15) == 0.2


def test_a_camera_without_h264_is_never_asked_for_rtsp() -> None:
    connects: list[object] = []
    told: list[bool] = []
    stage = H264Stage(lambda: H264Settings(), lambda _f: None)
    src = RtspH264Source(
        lambda *a: connects.append(a),  # type: ignore[arg-type,return-value]
        lambda: MediaStreamRequest(),
        stage,
        supports_h264=lambda: False,
        on_supported=told.append,
    )
    src.start()
    try:
        src.set_active(True)
        wait_until(lambda: told, timeout=2, raises=False)
        time.sleep(0.1)  # a window in which nothing may happen: no connect to a camera that said it has no H.264
    finally:
        src.stop()
    assert told == [False]
    assert src.supported is False
    assert not connects


def test_a_bitrate_change_is_applied_live_and_a_camera_that_refuses_adjustable_is_asked_without() -> None:
    units = _stream(40)
    asked: list[MediaStreamRequest] = []
    sessions: list[Session] = []

    class Refusing(Session):
        def open(self) -> None:
            raise RtspStatusError("RTSP DESCRIBE: 400 Bad Request", status_code=400)

    def connect(req: MediaStreamRequest, _t: float) -> Session:
        asked.append(req)
        s = Refusing([], CameraTimeout("x"), 0) if len(asked) == 1 else Session(units, CameraTimeout("stall"), 0)
        sessions.append(s)
        return s

    def adjustable_connect(req: MediaStreamRequest, _t: float) -> Session:
        asked.append(req)
        s = Session(units, CameraTimeout("stall"), 0)
        sessions.append(s)
        return s

    out: list[EncodedFrame] = []
    bitrate = [1000]
    for opener in (adjustable_connect, connect):
        asked.clear()
        sessions.clear()
        out.clear()
        bitrate[0] = 1000
        stage = H264Stage(lambda: H264Settings(), out.append)
        stage.set_active(True)
        src = RtspH264Source(
            opener,
            lambda: MediaStreamRequest(resolution="64x48", fps=15, max_bitrate_kbps=bitrate[0]),
            stage,
            supports_h264=lambda: True,
            on_supported=lambda _ok: None,
            config=_timing(read_timeout_s=0.5, stall_timeout_s=0.3),
        )
        src.start()
        try:
            src.set_active(True)
            wait_until(lambda: len(out) >= 5, timeout=5, raises=False)
            bitrate[0] = 1100  # a small move: live where adjustable, ignored (no reconnect) where not
            wait_until(lambda: len(out) >= 15, timeout=5, raises=False)
        finally:
            src.stop()
        playing = sessions[-1]
        if opener is adjustable_connect:
            assert [r.adjustable for r in asked] == [True]
            assert playing.adjusted == [1100]
            assert src.stats.adjustments == 1
        else:
            assert [r.adjustable for r in asked] == [True, False]  # refused with it: asked again without
            assert playing.adjusted == []
            assert src.stats.adjustments == 0
        assert len(out) >= 15


def test_a_camera_whose_rtsp_offers_no_h264_is_transcoded_not_asked_again() -> None:
    """It says it streams H.264, but its SDP has none (an event stream, RTP/JPEG): said once, then MJPEG is
    transcoded (``on_supported(False)``) instead of reconnecting forever with the same answer."""
    connects: list[object] = []
    told: list[bool] = []
    events: list[str] = []
    stage = H264Stage(lambda: H264Settings(), lambda _f: None)

    def connect(req: MediaStreamRequest, _timeout: float) -> Session:
        connects.append(req)
        raise NoH264VideoError("RTSP 127.0.0.1:554/axis-media/media.amp offers no H.264 video: m=video JPEG/90000")

    src = RtspH264Source(
        connect,
        lambda: MediaStreamRequest(),
        stage,
        supports_h264=lambda: True,
        on_supported=told.append,
        on_event=events.append,
        config=_timing(read_timeout_s=0.5, stall_timeout_s=0.1),
    )
    src.start()
    try:
        src.set_active(True)
        wait_until(lambda: told == [True, False], timeout=5, raises=False)
    finally:
        src.stop()
    assert told == [True, False]
    assert src.supported is False
    assert len(connects) == 1
    assert any("JPEG/90000" in e and "transcoding" in e for e in events), events


def test_a_step_of_this_hosts_clock_moves_the_stamps_with_it_and_is_logged() -> None:
    """The robot's clock steps back 10 s mid-stream (chrony finding its server): the frames after it are stamped on
    the new clock at once (their capture time, as every other stamp on the host), not frozen at the last stamp +
    1 ns until the clock catches up with it, and the step is logged."""
    units = _stream(60)
    offset = [0]  # this host's wall clock against the true time: steps by -10 s after the 30th access unit

    class Stepping(Session):
        def read(self, timeout_s: float | None = None) -> RtpAccessUnit:
            au = super().read(timeout_s)
            if self.sent == 31:
                offset[0] = -10 * 1_000_000_000
            return RtpAccessUnit(au.data, au.keyframe, self.sent * 6000, arrival_ns=time.time_ns() + offset[0])

    out: list[EncodedFrame] = []
    events: list[str] = []
    stage = H264Stage(lambda: H264Settings(), out.append)
    stage.set_active(True)
    session = Stepping(units, CameraTimeout("stall"), 0)
    src = RtspH264Source(
        lambda _req, _t: session,
        lambda: MediaStreamRequest(resolution="64x48", fps=15),
        stage,
        supports_h264=lambda: True,
        on_supported=lambda _ok: None,
        on_event=events.append,
        config=_timing(read_timeout_s=0.5, stall_timeout_s=0.1),
    )
    src.host_clock = WallClockSteps(wall_ns=lambda: time.time_ns() + offset[0])
    src.start()
    try:
        src.set_active(True)
        wait_until(lambda: len(out) >= 60, timeout=10, what="the session's 60 access units")
    finally:
        src.stop()
    jumps = [b.stamp_ns - a.stamp_ns for a, b in zip(out, out[1:], strict=False)]
    back = [j for j in jumps if j < 0]
    assert len(back) == 1  # once, at the step
    assert abs(back[0] + 10 * 1_000_000_000) < 200_000_000  # by the step (less the frame interval)
    assert all(j > 5_000_000 for j in jumps if j > 0)  # the frames' own pacing on either side, never 1 ns apart
    assert src.stamps.clamped == 0
    assert any("clock stepped by -10.0" in e for e in events)
