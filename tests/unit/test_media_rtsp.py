"""The RTSP side without a server: the VAPIX media URL, access-unit merging and RTSP reply parsing.

(The reader and SET_PARAMETER against a real RTSP server are in tests/integration/test_media_rtsp_server.py.)
"""

from __future__ import annotations

import urllib.parse

import pytest

from axis_ptz_ros2.vapix.errors import InvalidArgument, ResponseParseError
from axis_ptz_ros2.vapix.rtsp import MediaStreamRequest, parse_rtsp_response
from tests.support.pyav_rtsp import AccessUnitMerger, RtspReader

pytestmark = pytest.mark.unit


def test_media_url_asks_for_a_fixed_gop_baseline_and_a_max_bitrate() -> None:
    req = MediaStreamRequest(resolution="1280x720", fps=25, keyframe_interval=25, max_bitrate_kbps=1500)
    url = req.url("192.0.2.10", 554)
    parts = urllib.parse.urlsplit(url)
    assert (parts.scheme, parts.hostname, parts.port, parts.path) == (
        "rtsp",
        "192.0.2.10",
        554,
        "/axis-media/media.amp",
    )
    q = dict(urllib.parse.parse_qsl(parts.query))
    assert q == {
        "videocodec": "h264",
        "resolution": "1280x720",
        "fps": "25",
        "videozgopmode": "fixed",
        "videokeyframeinterval": "25",
        "h264profile": "baseline",
        "videobitratemode": "mbr",
        "videomaxbitrate": "1500",
        "audio": "0",
    }
    assert "videozprofile" not in url  # storage profile adds B-frames
    assert "adjustablelivestream=1" in MediaStreamRequest(adjustable=True).url("h")


def test_media_url_credentials_are_quoted_and_redacted_from_repr() -> None:
    url = MediaStreamRequest().url("cam.local", 8554, "root", "p@ss:w/rd")
    assert url.startswith("rtsp://root:p%40ss%3Aw%2Frd@cam.local:8554/")
    reader = RtspReader(url, secrets=("p@ss:w/rd",))
    assert "p%40ss" not in repr(reader)
    assert "root" not in repr(reader)
    assert "[::1]:554" in MediaStreamRequest().url("::1")


@pytest.mark.parametrize(
    ("kwargs", "reason"),
    [
        ({"resolution": "704*576"}, "resolution"),
        ({"resolution": "8x8"}, "resolution"),
        ({"fps": 0}, "fps"),
        ({"keyframe_interval": 0}, "keyframe interval"),
        ({"max_bitrate_kbps": 10}, "max bitrate"),
        ({"max_bitrate_kbps": True}, "max bitrate"),
    ],
)
def test_bad_stream_requests_are_refused(kwargs: dict[str, object], reason: str) -> None:
    with pytest.raises(InvalidArgument, match=reason):
        MediaStreamRequest(**kwargs)  # type: ignore[arg-type]


def test_packets_sharing_a_pts_are_one_access_unit() -> None:
    m = AccessUnitMerger()
    sps_pps = b"\x00\x00\x00\x01\x67\x42\x00\x1f\x00\x00\x00\x01\x68\xce"
    idr = b"\x00\x00\x00\x01\x65\x88"
    assert m.push(0, sps_pps) is None
    assert m.push(0, idr) is None  # same pts: the IDR FFmpeg's parser split off
    assert m.push(3000, b"\x00\x00\x00\x01\x41\x9a") == (0, sps_pps + idr)
    assert m.push(6000, b"\x00\x00\x00\x01\x41\x9b") == (3000, b"\x00\x00\x00\x01\x41\x9a")
    assert m.flush() == (6000, b"\x00\x00\x00\x01\x41\x9b")
    assert m.flush() is None
    assert m.merged == 1


def test_rtsp_reply_parsing() -> None:
    r = parse_rtsp_response(
        b'RTSP/1.0 401 Unauthorized\r\nCSeq: 2\r\nWWW-Authenticate: Digest realm="AXIS_X", nonce="ab"\r\n'
        b'WWW-Authenticate: Basic realm="AXIS_X"\r\nContent-Length: 0\r\n\r\n'
    )
    assert (r.status, r.reason, r.headers["cseq"]) == (401, "Unauthorized", "2")
    assert r.headers["www-authenticate"] == 'Digest realm="AXIS_X", nonce="ab", Basic realm="AXIS_X"'
    for bad in (b"HTTP/1.1 200 OK\r\n\r\n", b"RTSP/1.0 200 OK\r\nCSeq 1\r\n\r\n", b"RTSP/1.0 200 OK\r\n"):
        with pytest.raises(ResponseParseError):
            parse_rtsp_response(bad)
