"""Our RTSP client (vapix/rtsp_client.py) against a raw RTSP server that plays scripted camera replies
(tests/support/rtsp_script.py): SDP variants, Digest with and without qop, Basic only, a UDP transport answer, a
server request mid-stream, and hostile replies. The video is a real H.264 stream encoded with PyAV here.

Every failure must be a typed error (an :class:`AxisPtzError`) within the client's timeouts, never a hang or a
traceback, and no message may carry the password."""

from __future__ import annotations

import logging
import struct
import time

import av
import pytest

from axis_ptz_ros2.vapix.errors import AuthError, AxisPtzError, CameraTimeout, CameraUnreachable
from axis_ptz_ros2.vapix.rtsp import MediaStreamRequest, RtspControl
from axis_ptz_ros2.vapix.rtsp_client import RtspClient
from axis_ptz_ros2.vapix.rtsp_sdp import NoH264VideoError, UdpTransportError
from tests.support.rtsp_script import (
    CLOSE,
    Conn,
    H264Stream,
    RtpSender,
    Script,
    ScriptedRtspServer,
    encode_h264,
    h264_sdp,
)
from tests.support.waiting import wait_until

pytestmark = pytest.mark.integration

PASSWORD = "sCr1pted-secret"
STREAM = MediaStreamRequest(resolution="160x96", fps=30)


@pytest.fixture(scope="module")
def video() -> H264Stream:
    return encode_h264(40, gop=10)


def _client(server: ScriptedRtspServer, **kw: object) -> RtspClient:
    args: dict[str, object] = {
        "username": "root",
        "password": PASSWORD,
        "open_timeout_s": 3.0,
        "read_timeout_s": 2.0,
        "stream": STREAM,
    }
    args.update(kw)
    return RtspClient("127.0.0.1", server.port, **args)  # type: ignore[arg-type]


def _decode_all(units: list[bytes]) -> list[tuple[int, int]]:
    ctx = av.CodecContext.create("h264", "r")
    sizes = []
    for data in units:
        for frame in ctx.decode(av.Packet(data)):
            sizes.append((frame.width, frame.height))
    return sizes


def _no_secret(*texts: object) -> None:
    for text in texts:
        assert PASSWORD not in str(text)
        assert PASSWORD not in repr(text)


def streaming(video: H264Stream, *, fps: float = 60.0, loop: bool = False, reports: bool = True, **kw: object):  # type: ignore[no-untyped-def]
    """A ``play`` script: the stream's access units (and a sender report first), paced at ``fps``."""
    sender: RtpSender = kw.get("sender") or RtpSender()  # type: ignore[assignment]

    def play(conn: Conn) -> None:
        i = 0
        while True:
            for k, unit in enumerate(video.units):
                if reports and k % 20 == 0:
                    conn.send(sender.report(time.time_ns(), i))
                if not conn.send(sender.framed(unit, i)) or not conn.pace(1 / fps):
                    return
                i += 1
            if not loop:
                conn.pace(30)  # then silence until the client goes
                return

    return play, sender


def _script(video: H264Stream, **kw: object) -> Script:
    play, sender = streaming(video)
    args: dict[str, object] = {
        "sdp": h264_sdp(video),
        "password": PASSWORD,
        "play": play,
        "rtp_info": lambda _c: f"url=trackID=1;seq={sender.first_seq};rtptime={sender.rtp0}",
    }
    args.update(kw)
    return Script(**args)  # type: ignore[arg-type]


# ---- authentication ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("auth", ["digest", "digest-noqop"])
def test_digest_signs_every_request_of_the_session_and_the_nc_grows(video: H264Stream, auth: str) -> None:
    play, sender = streaming(video, loop=True)
    script = _script(video, auth=auth, play=play, session_timeout=3, rtp_info=lambda _c: f"seq={sender.first_seq}")
    with ScriptedRtspServer(script) as server:
        c = _client(server)
        with c:
            units = [c.read() for _ in range(25)]
            wait_until(lambda: "GET_PARAMETER" in server.methods(), 5, what="a keep-alive (timeout=3: every 1 s)")
            c.renew_stream()
        wait_until(lambda: "TEARDOWN" in server.methods(), 5, what="TEARDOWN")
        assert server.problems == []  # every request after the first challenge signed, nc growing
        signed = [r for r in server.requests if r.header("authorization")]
        assert [r.method for r in signed][-1] == "TEARDOWN"
        assert {"PLAY", "GET_PARAMETER", "SET_PARAMETER", "TEARDOWN"} <= {r.method for r in signed}
        assert "DESCRIBE" in server.methods()
        _no_secret(*[r.header("authorization") for r in server.requests], c)
    assert units[0].keyframe
    assert _decode_all([u.data for u in units]) == [(160, 96)] * 25
    assert (c.held_back, c.dropped, c.garbage_bytes, c.idr_requests, c._depack.errors) == (0, 0, 0, 0, 0)


def test_a_basic_only_camera_with_auth_auto_gets_the_hint_and_auth_basic_plays(
    video: H264Stream, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.DEBUG)
    with ScriptedRtspServer(_script(video, auth="basic")) as server:
        t0 = time.monotonic()
        with pytest.raises(AuthError) as info:
            _client(server).open()
        assert time.monotonic() - t0 < 3.0
        assert "set auth: basic" in str(info.value)
        assert not any(r.header("authorization") for r in server.requests)  # auto never sent it in clear
        with _client(server, auth="basic") as c:
            assert c.read().keyframe
        wait_until(lambda: "TEARDOWN" in server.methods(), 5)
        assert server.problems == []
        assert server.requests[-1].header("authorization").startswith("Basic ")
    _no_secret(info.value, caplog.text)


def test_wrong_password_is_an_auth_error_without_the_password(video: H264Stream) -> None:
    with ScriptedRtspServer(_script(video)) as server, pytest.raises(AuthError) as info:
        _client(server, password="not-" + PASSWORD).open()
    assert "check username/password" in str(info.value)
    assert "not-" not in str(info.value)
    _no_secret(info.value)


# ---- what the camera offers -------------------------------------------------------------------------------------
EVENTS_SDP = (
    "v=0\r\no=- 1 1 IN IP4 127.0.0.1\r\ns=Session streamed with GStreamer\r\nt=0 0\r\n"
    "m=application 0 RTP/AVP 98\r\na=rtpmap:98 vnd.onvif.metadata/90000\r\na=control:trackID=1\r\n"
)
JPEG_SDP = "v=0\r\ns=x\r\nt=0 0\r\nm=video 0 RTP/AVP 26\r\na=control:trackID=1\r\n"
MPEG4_SDP = "v=0\r\ns=x\r\nt=0 0\r\nm=video 0 RTP/AVP 96\r\na=rtpmap:96 MP4V-ES/90000\r\na=control:trackID=1\r\n"


@pytest.mark.parametrize(
    ("sdp", "says"),
    [
        (EVENTS_SDP, "m=application vnd.onvif.metadata/90000 (event stream)"),
        (JPEG_SDP, "m=video JPEG/90000"),
        (MPEG4_SDP, "m=video MP4V-ES/90000"),
        ("", "no media at all"),
    ],
)
def test_an_sdp_without_h264_video_says_what_the_camera_offers(sdp: str, says: str) -> None:
    with ScriptedRtspServer(Script(sdp=sdp, password=PASSWORD)) as server:
        t0 = time.monotonic()
        with pytest.raises(NoH264VideoError) as info:
            _client(server).open()
        assert time.monotonic() - t0 < 2.0  # not a read timeout
        assert "SETUP" not in server.methods()
    assert "the camera offers no H.264 video" in str(info.value)
    assert says in str(info.value)


def test_h264_after_an_audio_section_is_found_and_set_up_by_its_own_control(video: H264Stream) -> None:
    audio = "m=audio 0 RTP/AVP 0\r\na=rtpmap:0 PCMU/8000\r\na=control:trackID=2\r\n"
    script = _script(video, sdp=h264_sdp(video, payload_type=97, control="trackID=5", extra=audio))
    sender = RtpSender()

    def play(conn: Conn) -> None:
        for i, unit in enumerate(video.units[:5]):
            packets = [p[:1] + bytes([(p[1] & 0x80) | 97]) + p[2:] for p in sender.packets(unit, i)]
            conn.send(b"".join(struct.pack("!cBH", b"$", 0, len(p)) + p for p in packets))
        conn.pace(30)

    script.play = play
    script.rtp_info = lambda _c: f"url=trackID=5;seq={sender.first_seq}"
    with ScriptedRtspServer(script) as server, _client(server) as c:
        units = [c.read() for _ in range(5)]
        setup = next(r for r in server.requests if r.method == "SETUP" and r.header("authorization"))
        assert setup.uri.endswith("/trackID=5")
    assert units[0].keyframe
    assert len(_decode_all([u.data for u in units])) == 5


def test_a_setup_answered_with_udp_transport_is_a_clear_error(video: H264Stream) -> None:
    script = _script(video, transport=lambda _asked: "RTP/AVP;unicast;client_port=5000-5001;server_port=6970-6971")
    with ScriptedRtspServer(script) as server:
        t0 = time.monotonic()
        with pytest.raises(UdpTransportError) as info:
            _client(server).open()
        assert time.monotonic() - t0 < 2.0
        wait_until(lambda: "TEARDOWN" in server.methods(), 5, what="the session torn down")
        assert "PLAY" not in server.methods()
    assert "camera answered SETUP with UDP transport; only RTP over the RTSP TCP connection is supported" in str(
        info.value
    )


# ---- the stream ---------------------------------------------------------------------------------------------------
def test_the_first_idr_is_taken_without_rtp_info(video: H264Stream) -> None:
    with ScriptedRtspServer(_script(video, rtp_info=None)) as server, _client(server) as c:
        first = c.read()
    assert first.keyframe
    assert c.dropped == 0


def test_a_server_request_mid_stream_is_answered_and_the_stream_goes_on(video: H264Stream) -> None:
    sender = RtpSender()

    def play(conn: Conn) -> None:
        for i, unit in enumerate(video.units):
            if i == 5:
                conn.request("GET_PARAMETER", f"rtsp://127.0.0.1:{conn.server.port}/axis-media/media.amp")
            if i == 8:
                conn.request("OPTIONS")
            if i == 11:
                conn.request("ANNOUNCE")
            conn.send(sender.framed(unit, i))
            conn.pace(1 / 60)
        conn.pace(30)

    script = _script(video, play=play, rtp_info=lambda _c: f"seq={sender.first_seq}")
    with ScriptedRtspServer(script) as server, _client(server) as c:
        units = [c.read() for _ in range(30)]
        conn = server.conns[0]
        wait_until(lambda: len(conn.answers) == 3, 5, what="the client's answers")
    assert [a[0] for a in conn.answers] == ["RTSP/1.0 200 OK", "RTSP/1.0 200 OK", "RTSP/1.0 501 Not Implemented"]
    assert [a[1].get("cseq") for a in conn.answers] == ["101", "102", "103"]
    assert c.server_requests == 3
    assert len(_decode_all([u.data for u in units])) == 30
    assert c.dropped == 0


def test_a_lost_idr_holds_p_frames_until_the_next_idr_and_asks_for_one(video: H264Stream) -> None:
    sender = RtpSender()

    def play(conn: Conn) -> None:
        for i, unit in enumerate(video.units):
            packets = sender.packets(unit, i)
            if i == 10:  # the second IDR loses a fragment in its middle
                packets = packets[: len(packets) // 2] + packets[len(packets) // 2 + 1 :]
            conn.send(b"".join(struct.pack("!cBH", b"$", 0, len(p)) + p for p in packets))
            conn.pace(1 / 60)
        conn.pace(30)

    script = _script(video, play=play, rtp_info=lambda _c: f"seq={sender.first_seq}")
    with ScriptedRtspServer(script) as server, _client(server) as c:
        units = [c.read() for _ in range(len(video.units) - 10)]  # 0-9, then 20-39
        wait_until(lambda: "SET_PARAMETER" in server.methods(), 5, what="Renew-Stream")
        renew = next(r for r in server.requests if r.method == "SET_PARAMETER")
        assert renew.body == b"Renew-Stream: yes\r\n"
        assert renew.header("authorization")
        assert server.problems == []
    assert [u.keyframe for u in units[:11]] == [True] + [False] * 9 + [True]
    assert c.held_back == 9  # the P-frames of the lost IDR's GOP
    assert c.idr_requests == 1
    assert len(_decode_all([u.data for u in units])) == len(units)


@pytest.mark.parametrize("damage", ["doubled", "lost"])
def test_a_doubled_or_lost_p_frame_fragment_drops_that_access_unit_only(video: H264Stream, damage: str) -> None:
    sender = RtpSender(max_payload=200)

    def play(conn: Conn) -> None:
        for i, unit in enumerate(video.units[:20]):
            packets = sender.packets(unit, i)
            if i == 3 and len(packets) > 2:
                mid = len(packets) // 2
                if damage == "doubled":
                    packets = packets[: mid + 1] + [packets[mid]] + packets[mid + 1 :]
                else:
                    packets = packets[:mid] + packets[mid + 1 :]
            conn.send(b"".join(struct.pack("!cBH", b"$", 0, len(p)) + p for p in packets))
            conn.pace(1 / 60)
        conn.pace(30)

    assert len(RtpSender(max_payload=200).packets(video.units[3], 3)) > 2  # (a P-frame of several fragments)
    script = _script(video, play=play, rtp_info=lambda _c: f"seq={sender.first_seq}")
    with ScriptedRtspServer(script) as server, _client(server) as c:
        units = [c.read() for _ in range(19)]
    assert c.dropped == 1
    assert c.idr_requests == 0  # a P-frame: no IDR needed
    assert len(units) == 19


def test_garbage_between_interleaved_frames_is_skipped(video: H264Stream) -> None:
    sender = RtpSender()

    def play(conn: Conn) -> None:
        for i, unit in enumerate(video.units[:20]):
            conn.send(sender.framed(unit, i))
            if i % 4 == 1:
                conn.send(b"\r\n\x00garbage$\x07\x00\x10" + bytes(range(40)) + b"GET \r\n")
            conn.pace(1 / 60)
        conn.pace(30)

    script = _script(video, play=play, rtp_info=lambda _c: f"seq={sender.first_seq}")
    with ScriptedRtspServer(script) as server, _client(server) as c:
        units = [c.read() for _ in range(20)]
    assert c.garbage_bytes > 0
    assert c.dropped == 0
    assert len(_decode_all([u.data for u in units])) == 20


def test_sps_changing_mid_stream_is_passed_through(video: H264Stream) -> None:
    small = encode_h264(10, 160, 96, gop=10)
    large = encode_h264(10, 320, 192, gop=10, keep_parameter_sets=True, seed=3)  # new SPS in band
    sender = RtpSender()

    def play(conn: Conn) -> None:
        for i, unit in enumerate(small.units + large.units):
            conn.send(sender.framed(unit, i))
            conn.pace(1 / 60)
        conn.pace(30)

    script = _script(small, play=play, rtp_info=lambda _c: f"seq={sender.first_seq}")
    with ScriptedRtspServer(script) as server, _client(server) as c:
        units = [c.read() for _ in range(20)]
    assert _decode_all([u.data for u in units]) == [(160, 96)] * 10 + [(320, 192)] * 10


# ---- hostile replies: typed errors within the timeouts -------------------------------------------------------------
def _hostile(request: str, reply: bytes) -> Script:
    return Script(sdp="v=0\r\n", password=PASSWORD, auth="none", override={request: lambda _r, _c: reply})


@pytest.mark.parametrize(
    ("name", "script", "error"),
    [
        ("truncated then closed", _hostile("DESCRIBE", CLOSE), CameraUnreachable),
        ("headers never end", _hostile("DESCRIBE", b"RTSP/1.0 200 OK\r\nCSeq: 1\r\nContent-Le"), CameraTimeout),
        ("wrong CSeq", _hostile("DESCRIBE", b"RTSP/1.0 200 OK\r\nCSeq: 77\r\n\r\n"), CameraTimeout),
        ("no CSeq", _hostile("DESCRIBE", b"RTSP/1.0 200 OK\r\n\r\n"), CameraTimeout),
        (
            "body cut short",
            _hostile("DESCRIBE", b"RTSP/1.0 200 OK\r\nCSeq: 1\r\nContent-Length: 500\r\n\r\nv=0"),
            CameraTimeout,
        ),
        ("HTTP, not RTSP", _hostile("DESCRIBE", b"HTTP/1.1 400 Bad Request\r\n\r\n" * 3), AxisPtzError),
        ("bad status", _hostile("DESCRIBE", b"RTSP/1.0 2x0 OK\r\nCSeq: 1\r\n\r\n"), AxisPtzError),
        (
            "huge length",
            _hostile("DESCRIBE", b"RTSP/1.0 200 OK\r\nCSeq: 1\r\nContent-Length: 99999999999\r\n\r\n"),
            AxisPtzError,
        ),
        ("silence", _hostile("DESCRIBE", b""), CameraTimeout),
    ],
)
def test_hostile_replies_end_in_a_typed_error_in_time(name: str, script: Script, error: type[Exception]) -> None:
    with ScriptedRtspServer(script) as server:
        c = _client(server, open_timeout_s=1.5)
        t0 = time.monotonic()
        with pytest.raises(error) as info:
            c.open()
        took = time.monotonic() - t0
    assert isinstance(info.value, AxisPtzError)
    assert took < 1.5 + 1.0, f"{name}: {took:.1f} s"
    _no_secret(info.value)
    if name == "wrong CSeq":
        assert "CSeq 77" in str(info.value)


def test_a_reply_to_no_request_mid_stream_does_not_confuse_the_next_one(video: H264Stream) -> None:
    """A stray reply (wrong CSeq) before the real one: the real one answers renew_stream."""
    script = _script(video)
    script.override["SET_PARAMETER"] = lambda _r, cseq: (
        f"RTSP/1.0 200 OK\r\nCSeq: {cseq + 40}\r\n\r\nRTSP/1.0 200 OK\r\nCSeq: {cseq}\r\n\r\n".encode()
    )
    with ScriptedRtspServer(script) as server, _client(server) as c:
        c.read()
        assert c.renew_stream().status == 200
        c.read()


def test_the_connection_cut_mid_stream_is_a_lost_connection(video: H264Stream) -> None:
    sender = RtpSender()

    def play(conn: Conn) -> None:
        for i, unit in enumerate(video.units[:5]):
            data = sender.framed(unit, i)
            conn.send(data if i < 4 else data[: len(data) // 2])
            conn.pace(1 / 60)
        conn.sock.shutdown(2)

    script = _script(video, play=play, rtp_info=lambda _c: f"seq={sender.first_seq}")
    with ScriptedRtspServer(script) as server, _client(server) as c:
        for _ in range(4):
            c.read()
        t0 = time.monotonic()
        with pytest.raises(CameraUnreachable) as info:
            c.read()
        assert time.monotonic() - t0 < 2.5
    _no_secret(info.value)


def test_a_stream_that_stalls_is_a_read_timeout(video: H264Stream) -> None:
    play, sender = streaming(video)  # 40 frames, then silence
    script = _script(video, play=play, rtp_info=lambda _c: f"seq={sender.first_seq}")
    with ScriptedRtspServer(script) as server, _client(server, read_timeout_s=0.5) as c:
        for _ in range(len(video.units)):
            c.read()
        t0 = time.monotonic()
        with pytest.raises(CameraTimeout):
            c.read()
        assert time.monotonic() - t0 < 1.5


def test_rtsp_control_gives_the_same_basic_only_hint(video: H264Stream) -> None:
    with ScriptedRtspServer(_script(video, auth="basic")) as server:
        ctl = RtspControl("127.0.0.1", server.port, username="root", password=PASSWORD, stream=STREAM)
        try:
            with pytest.raises(AuthError) as info:
                ctl.describe()
        finally:
            ctl.close()
        ctl = RtspControl("127.0.0.1", server.port, username="root", password=PASSWORD, auth="basic", stream=STREAM)
        try:
            assert "H264/90000" in ctl.describe()
        finally:
            ctl.close()
    assert "set auth: basic" in str(info.value)
    _no_secret(info.value)


def test_a_nonce_gone_stale_mid_session_is_renewed_by_the_keep_alive(video: H264Stream) -> None:
    play, sender = streaming(video, loop=True)
    script = _script(
        video, play=play, session_timeout=3, nonce_uses=3, rtp_info=lambda _c: f"seq={sender.first_seq}"
    )  # DESCRIBE, SETUP, PLAY use up the first nonce: the first keep-alive finds it stale
    with ScriptedRtspServer(script) as server:
        with _client(server) as c:
            c.read()
            wait_until(lambda: server.methods().count("GET_PARAMETER") >= 2, 5, what="a keep-alive, stale, retried")
            wait_until(lambda: server.stale_answers >= 1, 5)
            keepalives = [r for r in server.requests if r.method == "GET_PARAMETER"]
            assert keepalives[0].header("authorization") != keepalives[1].header("authorization")
            for _ in range(30):  # the session goes on
                c.read()
            assert c.renew_stream().status == 200
            assert c.background_errors == 0, c.last_background_error
        assert server.problems == []
