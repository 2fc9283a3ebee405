"""The RTSP side's text from the network, generated (issue 25): RTSP replies (status line, headers, body), SDP
with odd ``sprop-parameter-sets``, ``a=control`` and media sections, ``Transport`` and ``RTP-Info`` headers. Every
parser answers with a value in range or a typed refusal (``ResponseParseError``, an ``AxisPtzError``), never
another exception."""

from __future__ import annotations

import base64

import pytest
from hypothesis import given
from hypothesis import strategies as st

from axis_ptz_ros2.vapix.errors import AxisPtzError
from axis_ptz_ros2.vapix.rtsp import parse_rtsp_response, sprop_parameter_sets
from axis_ptz_ros2.vapix.rtsp_sdp import interleaved_channels, rtp_info_seq, sdp_control

pytestmark = pytest.mark.fuzz

_header_line = st.one_of(
    st.text(max_size=60).filter(lambda s: "\r" not in s and "\n" not in s),
    st.sampled_from(
        [
            "CSeq: 3",
            "Session: 1234;timeout=60",
            "Content-Length: 99999999999999",
            "Content-Type: application/sdp",
            'WWW-Authenticate: Digest realm="x", nonce=""',
            ":",
            "Transport: RTP/AVP/TCP;interleaved=0-1",
        ]
    ),
)
_status_line = st.one_of(
    st.text(max_size=40).filter(lambda s: "\r" not in s and "\n" not in s),
    st.sampled_from(
        [
            "RTSP/1.0 200 OK",
            "RTSP/1.0 ²00 OK",
            "RTSP/1.0 99999999999999999999 X",
            "RTSP/1.0 200",
            "HTTP/1.1 200 OK",
            "RTSP/1.0 -1 X",
            "RTSP/1.0 ٤٠٤ Not Found",
        ]
    ),
)


@given(_status_line, st.lists(_header_line, max_size=8), st.binary(max_size=64), st.booleans())
def test_rtsp_replies(status: str, headers: list[str], body: bytes, ended: bool) -> None:
    raw = ("\r\n".join([status, *headers])).encode("utf-8", "surrogatepass") + (b"\r\n\r\n" if ended else b"") + body
    try:
        reply = parse_rtsp_response(raw)
    except AxisPtzError as err:
        refusal = str(err)
    else:
        assert 100 <= reply.status <= 999
        assert all(k == k.lower() for k in reply.headers)
        return
    assert refusal


_b64_item = st.one_of(
    st.binary(max_size=40).map(lambda b: base64.b64encode(b).decode()),
    st.text(max_size=20),
    st.sampled_from(["Z0LAHtkDxWhAAAADAEAAAA8jxYuS", "aMuMsg==", "", "====", "Z0L", "AAAA"]),
)
_fmtp = st.lists(_b64_item, max_size=4).map(
    lambda items: "a=fmtp:96 packetization-mode=1;sprop-parameter-sets=" + ",".join(items)
)
_sdp_line = st.one_of(
    _fmtp,
    st.sampled_from(
        ["v=0", "m=video 0 RTP/AVP 96", "m=audio 0 RTP/AVP 0", "a=control:trackID=1", "a=control:", "a=fmtp:96"]
    ),
    st.text(max_size=40).filter(lambda s: "\n" not in s and "\r" not in s),
)


@given(st.lists(_sdp_line, max_size=10))
def test_sdp(lines: list[str]) -> None:
    sdp = "\r\n".join(lines)
    refusal = ""
    try:
        sets = sprop_parameter_sets(sdp)
    except AxisPtzError as err:
        refusal, sets = str(err), None
    assert not refusal or "sprop-parameter-sets" in refusal
    if sets is not None:
        assert sets.sps[0] & 0x1F == 7
        assert sets.pps[0] & 0x1F == 8
    for video in (True, False):
        assert isinstance(sdp_control(sdp, video=video), str)


@given(
    st.one_of(
        st.text(max_size=60),
        st.sampled_from(
            [
                "RTP/AVP/TCP;interleaved=0-1",
                "interleaved=300-301",
                "interleaved=99999999999999999999",
                "interleaved=²-1",
                "interleaved=-",
                "interleaved=4-",
            ]
        ),
    )
)
def test_transport_header(transport: str) -> None:
    try:
        rtp, rtcp = interleaved_channels(transport)
    except AxisPtzError as err:
        rtp, rtcp, refusal = 0, 0, str(err)
    else:
        refusal = "interleaved"
    assert "interleaved" in refusal
    assert 0 <= rtp <= 255
    assert 0 <= rtcp <= 255


@given(
    st.one_of(
        st.text(max_size=60),
        st.sampled_from(
            [
                "url=rtsp://x/trackID=1;seq=123;rtptime=0",
                "seq=99999999999999999999",
                "seq=²",
                "seq=",
                "url=a;seq=7,url=b;seq=8",
            ]
        ),
    )
)
def test_rtp_info_header(rtp_info: str) -> None:
    seq = rtp_info_seq(rtp_info)
    assert seq is None or 0 <= seq <= 0xFFFF
