"""The pass-through source's stamps (streaming/rtsp_source.py + streaming/clock_sync.py) with our real RTSP client
against a scripted camera whose wall clock is 30 s behind, then stepped back by another 30 s, then lost and
reconnected: stamps stay on the host's clock and never go backwards; the camera's offset is in the stats and is
reported once."""

from __future__ import annotations

import threading
import time

import pytest

from axis_ptz_ros2.media.frame import EncodedFrame
from axis_ptz_ros2.streaming.reader import ReaderConfig
from axis_ptz_ros2.streaming.rtsp_source import RtspH264Source
from axis_ptz_ros2.vapix.rtsp import MediaStreamRequest
from axis_ptz_ros2.vapix.rtsp_client import RtspClient
from tests.support.rtsp_script import Conn, RtpSender, Script, ScriptedRtspServer, encode_h264, h264_sdp
from tests.support.waiting import wait_until

pytestmark = pytest.mark.integration

NS = 1_000_000_000
PASSWORD = "stamp-secret"


class Sink:
    """Records what the source hands out, with the host time it was handed out."""

    def __init__(self) -> None:
        self.got: list[tuple[int, int, bool]] = []  # (stamp, host time at hand-over, keyframe)
        self.lock = threading.Lock()

    def on_access_unit(self, frame: EncodedFrame, stamp_ns: int) -> object:
        with self.lock:
            self.got.append((stamp_ns, time.time_ns(), frame.keyframe))
        return frame

    @property
    def idr_wanted(self) -> bool:
        return False

    def idr_sent(self) -> None:
        pass

    def count(self) -> int:
        with self.lock:
            return len(self.got)


def test_stamps_on_the_host_clock_across_a_camera_clock_step_and_a_reconnect() -> None:
    video = encode_h264(30, gop=15)
    behind = [30 * NS]  # the camera's wall clock: host − this
    sessions: list[Conn] = []

    def play(conn: Conn) -> None:
        sessions.append(conn)
        sender = conn.sender  # type: ignore[attr-defined]
        i = 0
        while True:
            unit = video.units[i % len(video.units)]
            if i % 15 == 0:  # a sender report every half second, sent as the frame is
                conn.send(sender.report(time.time_ns() - behind[0], i))
            if not conn.send(sender.framed(unit, i)) or not conn.pace(1 / 30):
                return
            i += 1

    def rtp_info(conn: Conn) -> str:
        conn.sender = RtpSender()  # type: ignore[attr-defined]  # a new RTP origin per session
        return f"seq={conn.sender.first_seq}"  # type: ignore[attr-defined]

    script = Script(sdp=h264_sdp(video), password=PASSWORD, play=play, rtp_info=rtp_info)
    events: list[str] = []
    sink = Sink()
    with ScriptedRtspServer(script) as server:

        def connect(req: MediaStreamRequest, read_timeout_s: float) -> RtspClient:
            return RtspClient(
                "127.0.0.1",
                server.port,
                stream=req,
                username="root",
                password=PASSWORD,
                open_timeout_s=3.0,
                read_timeout_s=read_timeout_s,
            )

        src = RtspH264Source(
            connect,
            lambda: MediaStreamRequest(resolution="160x96", fps=30),
            sink,
            supports_h264=lambda: True,
            on_supported=lambda _ok: None,
            on_event=events.append,
            config=ReaderConfig(backoff_initial_s=0.05, backoff_max_s=0.2, read_timeout_s=1.0),
        )
        src.start()
        try:
            src.set_active(True)
            wait_until(lambda: sink.count() >= 60, 10, what="two seconds of frames")
            offset = src.stats.camera_clock_offset_s
            assert offset is not None
            assert abs(offset - 30) < 0.1, offset
            behind[0] = 60 * NS  # NTP steps the camera's clock back by another 30 s
            n = sink.count()
            wait_until(lambda: sink.count() >= n + 45, 10)
            offset = src.stats.camera_clock_offset_s
            assert offset is not None
            assert abs(offset - 60) < 0.1, offset
            sessions[0].sock.shutdown(2)  # the camera drops the connection: a new session, a new RTP origin
            wait_until(lambda: len(sessions) >= 2, 10, what="a reconnect")
            n = sink.count()
            wait_until(lambda: sink.count() >= n + 30, 10)
        finally:
            src.stop()
    got = list(sink.got)
    stamps = [s for s, _, _ in got]
    assert all(b > a for a, b in zip(stamps, stamps[1:], strict=False)), "a stamp went backwards"
    # stamped on the host's clock: never after the hand-over, and within the stream's latency before it
    late = [(handed - s) / 1e6 for s, handed, _ in got]
    assert min(late) >= 0, min(late)
    assert max(late) < 300, max(late)  # (a loaded machine's scheduling: ms here, nothing like 30 s)
    warnings = [e for e in events if "set NTP on the camera" in e]
    assert len(warnings) == 1, events
    assert "30." in warnings[0]
    assert "behind" in warnings[0]
    assert src.stats.connects >= 2
