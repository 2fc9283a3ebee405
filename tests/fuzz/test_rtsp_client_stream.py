"""What arrives on our RTSP client's connection, generated (issue 40): interleaved frames (whole, cut, with a
wrong channel or length), replies, server requests, garbage, in any order and cut into any chunks. The client's
message loop must handle it or refuse it with a typed error (an :class:`AxisPtzError`), never another exception,
and never buffer without bound. And any SDP text gives an H.264 media or :class:`NoH264VideoError`."""

from __future__ import annotations

import struct

import pytest
from hypothesis import given
from hypothesis import strategies as st

from axis_ptz_ros2.media import annexb
from axis_ptz_ros2.sim.rtsp.rtp import H264Packetizer, interleave, sender_report
from axis_ptz_ros2.vapix.errors import AxisPtzError
from axis_ptz_ros2.vapix.rtsp_client import RtspClient
from axis_ptz_ros2.vapix.rtsp_connection import MAX_MESSAGE
from axis_ptz_ros2.vapix.rtsp_sdp import NoH264VideoError, h264_media

pytestmark = pytest.mark.fuzz

_PACKETIZER = H264Packetizer(max_payload=60, ssrc=7)
_AU = annexb.join_nal_units([bytes([0x65, 0x88]) + bytes(range(1, 150)), bytes([0x41, 0x9A]) + bytes(range(1, 40))])
_FRAMES = [interleave(0, p) for p in _PACKETIZER.packetize(_AU, 3000)]

_piece = st.one_of(
    st.sampled_from(_FRAMES),
    st.sampled_from(_FRAMES).map(lambda f: f[: len(f) // 2]),  # cut
    st.just(interleave(1, sender_report(7, 1_700_000_000 * 10**9, 3000, 1, 100, "x"))),
    st.just(interleave(5, b"\x80\x60" + b"\x00" * 20)),  # a channel nobody set up
    st.just(struct.pack("!cBH", b"$", 0, 65535) + b"\x80"),  # a length running past what comes
    st.just(b"RTSP/1.0 200 OK\r\nCSeq: 3\r\n\r\n"),
    st.just(b"RTSP/1.0 200 OK\r\nContent-Length: 4\r\n\r\nabcd"),
    st.just(b"RTSP/1.0 2x0 OK\r\n\r\n"),
    st.just(b"GET_PARAMETER rtsp://cam/ RTSP/1.0\r\nCSeq: 9\r\n\r\n"),
    st.just(b"OPTIONS * RTSP/1.0\r\nCSeq: 10\r\nContent-Length: 2\r\n\r\nhi"),
    st.just(b"ANNOUNCE * RTSP/1.0\r\nContent-Length: 99999999999\r\n\r\n"),
    st.binary(max_size=80),
    st.text(max_size=30).map(lambda t: t.encode("utf-8", "surrogatepass")),
)


@given(st.lists(_piece, max_size=25), st.lists(st.integers(1, 200), min_size=1, max_size=10))
def test_the_message_loop_takes_anything_or_refuses_it_typed(pieces: list[bytes], cuts: list[int]) -> None:
    c = RtspClient("127.0.0.1", 9, password="fuzz-secret-pw", username="u")
    c._params = annexb.ParameterSetTracker(None)  # noqa: SLF001 - as open() leaves it
    data = b"".join(pieces)
    pos, i = 0, 0
    refusal = ""
    try:
        while pos < len(data):
            step = cuts[i % len(cuts)]
            c._buf += data[pos : pos + step]  # noqa: SLF001 - the bytes as _pump would append them
            pos, i = pos + step, i + 1
            while c._take_message():  # noqa: SLF001
                pass
            assert len(c._buf) <= 4 * MAX_MESSAGE  # noqa: SLF001
    except AxisPtzError as err:
        refusal = str(err)
    assert "fuzz-secret-pw" not in refusal
    assert len(c._queue) <= c._queue.maxlen  # type: ignore[operator]  # noqa: SLF001


_sdp_line = st.one_of(
    st.sampled_from(
        [
            "m=video 0 RTP/AVP 96",
            "m=video 0 RTP/AVP 26",
            "m=application 0 RTP/AVP 98",
            "m=audio 0 RTP/AVP 0 97",
            "m=",
            "m=video",
            "a=rtpmap:96 H264/90000",
            "a=rtpmap:96 h264/90000/1",
            "a=rtpmap:98 vnd.onvif.metadata/90000",
            "a=rtpmap:96 H264/8000",
            "a=rtpmap:",
            "a=rtpmap:x H264/90000",
            "a=control:trackID=1",
            "a=control:rtsp://cam/x",
        ]
    ),
    st.text(max_size=40).filter(lambda s: "\n" not in s and "\r" not in s),
)


@given(st.lists(_sdp_line, max_size=12))
def test_any_sdp_gives_h264_media_or_says_what_is_offered(lines: list[str]) -> None:
    sdp = "\r\n".join(lines)
    try:
        control, payload_type = h264_media(sdp, "RTSP DESCRIBE cam")
    except NoH264VideoError as err:
        refusal = str(err)
        assert "the camera offers no H.264 video: " in refusal
        assert len(refusal) < 400
        return
    assert isinstance(control, str)
    assert 0 <= payload_type <= 127
    assert "m=video" in sdp
    assert "H264/90000" in sdp.upper() or "h264/90000" in sdp.lower()
