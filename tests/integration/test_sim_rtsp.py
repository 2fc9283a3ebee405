"""The simulated current Axis (q6075) serves RTSP H.264 that clients nobody here wrote play: FFmpeg through PyAV
(Digest, RTP over the RTSP TCP connection), plus a raw socket client for what FFmpeg cannot show or send (the
session's own SET_PARAMETER, the exact replies)."""

from __future__ import annotations

import hashlib
import re
import socket
import struct
import time
from collections.abc import Iterator

import av
import av.error
import cv2
import numpy as np
import pytest

from axis_ptz_ros2.media import annexb
from axis_ptz_ros2.sim.camera import SimulatedCamera
from axis_ptz_ros2.sim.frames import MAX_COMPRESSION, MAX_FPS
from axis_ptz_ros2.sim.rtsp.server import RtspListener
from tests.support.picture import psnr_db
from tests.support.waiting import wait_until

pytestmark = pytest.mark.integration

PASSWORD = "rtsp-secret"
QUERY = "videocodec=h264&resolution=640x360&fps=15&videokeyframeinterval=300&videozgopmode=fixed"
OPEN = {"rtsp_transport": "tcp", "timeout": "4000000"}


@pytest.fixture(scope="module")
def cam() -> Iterator[SimulatedCamera]:
    with SimulatedCamera(model="q6075", https=False, password=PASSWORD, rtsp_session_timeout_s=2.0) as c:
        c.teleport(20.0, -5.0, 1.0)
        yield c


def _url(cam: SimulatedCamera, query: str = QUERY, password: str = PASSWORD) -> str:
    assert cam.rtsp is not None
    return f"rtsp://root:{password}@127.0.0.1:{cam.rtsp.port}/axis-media/media.amp?{query}"


# ---- FFmpeg (PyAV) as the client ---------------------------------------------------------------------------------
def test_pyav_plays_frames_of_the_asked_size_matching_the_mjpeg_snapshot(cam: SimulatedCamera) -> None:
    with av.open(_url(cam), options=OPEN, timeout=(8, 5)) as c:
        stream = c.streams.video[0]
        assert stream.codec_context.name == "h264"
        assert (stream.codec_context.width, stream.codec_context.height) == (640, 360)
        frames = []
        for frame in c.decode(video=0):
            frames.append(frame.to_ndarray(format="bgr24"))
            if len(frames) == 10:
                break
    snapshot = cv2.imdecode(np.frombuffer(cam.frame_jpeg(640, 360, 0), np.uint8), cv2.IMREAD_COLOR)
    assert all(f.shape == (360, 640, 3) for f in frames)
    psnr = psnr_db(frames[-1], snapshot)
    assert psnr >= 30.0, f"the H.264 picture is not the MJPEG view: {psnr:.1f} dB"
    other = cv2.imdecode(np.frombuffer(cam.frames.frame_jpeg(640, 360, 0, "x" * 40), np.uint8), cv2.IMREAD_COLOR)
    assert psnr_db(frames[-1], np.roll(other, 64, axis=1)) < psnr  # the check can fail: a shifted view scores less


def test_pyav_probe_lists_the_stream(cam: SimulatedCamera) -> None:
    """What ``ffprobe`` prints, from PyAV's bundled FFmpeg (Debian's ffmpeg is not installed here)."""
    with av.open(_url(cam), options=OPEN, timeout=(8, 5)) as c:
        (stream,) = c.streams
        assert stream.type == "video"
        assert stream.codec_context.name == "h264"
        assert stream.codec_context.profile in ("Constrained Baseline", "Baseline")
        assert stream.time_base is not None
        assert stream.time_base.denominator == 90000
        assert c.format.name == "rtsp"


def test_rtcp_sender_reports_give_the_capture_time_of_the_sei_stamp(cam: SimulatedCamera) -> None:
    offsets = []
    with av.open(_url(cam), options=OPEN, timeout=(8, 5)) as c:
        stream = c.streams.video[0]
        deadline = time.monotonic() + 10
        for pkt in c.demux(stream):
            if time.monotonic() > deadline or len(offsets) >= 20:
                break
            stamp = annexb.extract_capture_stamp(bytes(pkt)) if pkt.size else None
            if stamp is None or pkt.pts is None or not c.start_time_realtime:
                continue
            capture_s = c.start_time_realtime / 1e6 + float(pkt.pts * stream.time_base)
            offsets.append(capture_s - stamp / 1e9)
    assert len(offsets) >= 10, "no RTCP sender report or no capture-time SEI"
    assert max(abs(o) for o in offsets) < 0.1, offsets


def test_wrong_password_is_refused(cam: SimulatedCamera) -> None:
    with pytest.raises(av.error.HTTPUnauthorizedError):
        av.open(_url(cam, password="wrong"), options=OPEN, timeout=(8, 5))


# ---- a raw client: exact replies, the session's own SET_PARAMETER ---------------------------------------------
class RawRtsp:
    """Plain sockets and RFC 2617 Digest (qop=auth), written out here so nothing of ours is in the loop."""

    def __init__(self, cam: SimulatedCamera, password: str = PASSWORD) -> None:
        assert cam.rtsp is not None
        self.base = f"rtsp://127.0.0.1:{cam.rtsp.port}"
        self.password = password
        self.sock = socket.create_connection(("127.0.0.1", cam.rtsp.port), timeout=5)
        self.cseq = 0
        self.buf = b""
        self.challenge: dict[str, str] | None = None
        self.rtp: list[bytes] = []
        self.rtcp: list[bytes] = []

    def close(self) -> None:
        self.sock.close()

    def _auth(self, method: str, uri: str) -> str | None:
        if self.challenge is None:
            return None
        c = self.challenge
        h = lambda s: hashlib.md5(s.encode()).hexdigest()  # noqa: E731, S324
        ha1, ha2, nc, cnonce = h(f"root:{c['realm']}:{self.password}"), h(f"{method}:{uri}"), "00000001", "abcd"
        resp = h(f"{ha1}:{c['nonce']}:{nc}:{cnonce}:auth:{ha2}")
        return (
            f'Digest username="root", realm="{c["realm"]}", nonce="{c["nonce"]}", uri="{uri}", '
            f'response="{resp}", algorithm=MD5, qop=auth, nc={nc}, cnonce="{cnonce}"'
        )

    def request(
        self, method: str, uri: str, headers: dict[str, str] | None = None, body: bytes = b""
    ) -> tuple[int, dict[str, str], bytes]:
        for _ in range(2):
            self.cseq += 1
            lines = [f"{method} {uri} RTSP/1.0", f"CSeq: {self.cseq}"]
            auth = self._auth(method, uri)
            if auth:
                lines.append(f"Authorization: {auth}")
            lines += [f"{k}: {v}" for k, v in (headers or {}).items()]
            if body:
                lines.append(f"Content-Length: {len(body)}")
            self.sock.sendall(("\r\n".join(lines) + "\r\n\r\n").encode() + body)
            status, hdrs, rbody = self.reply()
            if status == 401 and self.challenge is None:
                self.challenge = dict(re.findall(r'(\w+)="([^"]*)"', hdrs["www-authenticate"]))
                continue
            return status, hdrs, rbody
        return status, hdrs, rbody

    def _fill(self) -> None:
        chunk = self.sock.recv(65536)
        if not chunk:
            raise ConnectionError("closed by the camera")
        self.buf += chunk

    def _interleaved(self) -> bool:
        """Take one interleaved frame off the buffer if complete; False if more bytes are needed."""
        if len(self.buf) < 4:
            return False
        n = struct.unpack("!H", self.buf[2:4])[0]
        if len(self.buf) < 4 + n:
            return False
        (self.rtp if self.buf[1] == 0 else self.rtcp).append(self.buf[4 : 4 + n])
        self.buf = self.buf[4 + n :]
        return True

    def reply(self) -> tuple[int, dict[str, str], bytes]:
        while True:
            if self.buf[:1] == b"$":
                if not self._interleaved():
                    self._fill()
                continue
            end = self.buf.find(b"\r\n\r\n")
            if end < 0:
                self._fill()
                continue
            head = self.buf[:end].decode().split("\r\n")
            hdrs = {k.strip().lower(): v.strip() for k, _, v in (line.partition(":") for line in head[1:])}
            n = int(hdrs.get("content-length", "0"))
            while len(self.buf) < end + 4 + n:
                self._fill()
            body = self.buf[end + 4 : end + 4 + n]
            self.buf = self.buf[end + 4 + n :]
            return int(head[0].split()[1]), hdrs, body

    def pump(self, seconds: float) -> None:
        """Read interleaved data for ``seconds``."""
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            while self.buf[:1] == b"$" and self._interleaved():
                pass
            self._fill()

    def play(self, query: str = QUERY) -> tuple[str, str]:
        url = f"{self.base}/axis-media/media.amp?{query}"
        status, hdrs, sdp = self.request("DESCRIBE", url, {"Accept": "application/sdp"})
        assert status == 200, status
        control = re.search(rb"a=control:(\S+/stream=0\S*)", sdp)
        assert control is not None
        status, hdrs, _ = self.request(
            "SETUP", control.group(1).decode(), {"Transport": "RTP/AVP/TCP;unicast;interleaved=0-1"}
        )
        assert status == 200, status
        session = hdrs["session"].split(";")[0]
        status, _, _ = self.request("PLAY", url, {"Session": session, "Range": "npt=0.000-"})
        assert status == 200
        return session, hdrs["session"]


def _nal_types(packets: list[bytes]) -> list[tuple[int, int]]:
    """(marker, nal type) of every NAL unit start in RTP packets (single NAL units and FU-A starts)."""
    out = []
    for p in packets:
        payload, marker = p[12:], p[1] >> 7
        t = payload[0] & 0x1F
        if t == 28:
            if payload[1] & 0x80:
                out.append((marker, payload[1] & 0x1F))
        else:
            out.append((marker, t))
    return out


@pytest.fixture
def raw(cam: SimulatedCamera) -> Iterator[RawRtsp]:
    r = RawRtsp(cam)
    yield r
    r.close()


def test_sdp_carries_parameter_sets_and_the_stream_does_not(raw: RawRtsp) -> None:
    status, hdrs, sdp = raw.request("DESCRIBE", f"{raw.base}/axis-media/media.amp?{QUERY}")
    assert status == 200
    assert hdrs["content-type"] == "application/sdp"
    fmtp = re.search(rb"profile-level-id=([0-9A-F]{6});sprop-parameter-sets=([^\r\n;]+)", sdp)
    assert fmtp is not None
    sets = annexb.parse_sprop_parameter_sets(fmtp.group(2).decode())
    assert (sets.info.width, sets.info.height) == (640, 360)
    assert fmtp.group(1).decode() == sets.sps[1:4].hex().upper()
    raw.play()
    raw.pump(1.5)
    types = _nal_types(raw.rtp)
    assert annexb.NalType.IDR in [t for _, t in types]
    assert annexb.NalType.SPS not in [t for _, t in types]
    assert annexb.NalType.PPS not in [t for _, t in types]
    assert any(len(p) > 1000 for p in raw.rtp)  # FU-A in use …
    assert all(len(p) <= 1412 for p in raw.rtp)  # … and no packet over the payload size
    assert raw.rtcp
    assert raw.rtcp[0][1] == 200  # sender reports


def test_renew_stream_makes_the_next_frame_an_idr(raw: RawRtsp) -> None:
    session, _ = raw.play()
    raw.pump(1.5)
    before = [t for _, t in _nal_types(raw.rtp)].count(annexb.NalType.IDR)
    assert before == 1  # keyframe interval 300 at 15 fps: only the first
    raw.rtp.clear()
    status, _, _ = raw.request(
        "SET_PARAMETER",
        f"{raw.base}/axis-media/media.amp",
        {"Session": session, "Content-Type": "text/parameters"},
        b"Renew-Stream: yes\r\n",
    )
    assert status == 200
    raw.pump(0.6)
    types = [t for _, t in _nal_types(raw.rtp)]
    assert types.count(annexb.NalType.IDR) == 1
    status, _, _ = raw.request(
        "SET_PARAMETER", f"{raw.base}/axis-media/media.amp", {"Session": session}, b"Bogus: 1\r\n"
    )
    assert status == 451
    status, _, _ = raw.request(
        "SET_PARAMETER", f"{raw.base}/axis-media/media.amp", {"Session": "NOPE"}, b"Renew-Stream: yes\r\n"
    )
    assert status == 454


def test_adjustable_stream_fps_runs_to_the_cameras_top(raw: RawRtsp) -> None:
    session, _ = raw.play(QUERY + "&adjustablelivestream=1")

    def adjust(value: str) -> int:
        return raw.request(
            "SET_PARAMETER",
            f"{raw.base}/axis-media/media.amp",
            {"Session": session, "Content-Type": "text/parameters"},
            f"Adjustable-Stream-Configuration: {value}\r\n".encode(),
        )[0]

    assert [adjust(f"fps={f}") for f in (1, MAX_FPS, MAX_FPS + 1, 0)] == [200, 200, 400, 400]


def test_wrong_password_gets_the_http_sides_digest_challenge(cam: SimulatedCamera) -> None:
    r = RawRtsp(cam, password="wrong")
    try:
        status, hdrs, _ = r.request("DESCRIBE", f"{r.base}/axis-media/media.amp?{QUERY}")
        assert status == 401
        assert re.fullmatch(
            r'Digest realm="AXIS_[0-9A-F]{12}", nonce="[^"]+", algorithm=MD5, qop="auth"', hdrs["www-authenticate"]
        )
    finally:
        r.close()


@pytest.mark.parametrize(
    ("query", "status"),
    [
        ("videocodec=h264&resolution=123x45", 400),
        ("videocodec=h264&fps=99", 400),
        (f"videocodec=h264&fps={MAX_FPS}", 200),
        (f"videocodec=h264&compression={MAX_COMPRESSION + 1}", 400),
        (f"videocodec=h264&compression={MAX_COMPRESSION}", 200),
        ("videocodec=h264&videokeyframeinterval=0", 400),
        ("videocodec=h264&videomaxbitrate=1000", 400),  # a rate option without videobitratemode
        ("videocodec=h264&videobitratemode=mbr&videomaxbitrate=10", 400),
        ("videocodec=h264&h264profile=extended", 400),
        ("videocodec=h265", 415),
        ("videocodec=h264&videobitratemode=mbr&videomaxbitrate=800&h264profile=baseline", 200),
    ],
)
def test_media_arguments_are_validated(raw: RawRtsp, query: str, status: int) -> None:
    assert raw.request("DESCRIBE", f"{raw.base}/axis-media/media.amp?{query}")[0] == status


def test_unknown_path_is_404(raw: RawRtsp) -> None:
    assert raw.request("DESCRIBE", f"{raw.base}/mpeg4/media.amp")[0] == 404
    assert raw.request("OPTIONS", "*")[0] == 200


def test_udp_transport_is_refused(raw: RawRtsp) -> None:
    status, _, _ = raw.request(
        "SETUP",
        f"{raw.base}/axis-media/media.amp/stream=0?{QUERY}",
        {"Transport": "RTP/AVP;unicast;client_port=5000-5001"},
    )
    assert status == 461


def test_a_session_without_keep_alive_times_out(raw: RawRtsp) -> None:
    _, header = raw.play()
    assert header.endswith(";timeout=2")
    t0 = time.monotonic()
    with pytest.raises(ConnectionError):
        raw.pump(10)
    assert 1.8 < time.monotonic() - t0 < 4.0


def test_keep_alive_keeps_the_session(raw: RawRtsp) -> None:
    session, _ = raw.play()
    for _ in range(4):
        raw.pump(0.8)
        assert raw.request("GET_PARAMETER", f"{raw.base}/axis-media/media.amp", {"Session": session})[0] == 200
    assert raw.request("TEARDOWN", f"{raw.base}/axis-media/media.amp", {"Session": session})[0] == 200


def test_the_214_has_no_h264() -> None:
    with SimulatedCamera() as old:
        assert old.rtsp is None  # no RTSP server on the 214 persona
        listener = RtspListener(old, "127.0.0.1", 0)
        listener.open()
        try:
            s = socket.create_connection(("127.0.0.1", listener.port), timeout=5)
            s.sendall(
                f"DESCRIBE rtsp://127.0.0.1:{listener.port}/axis-media/media.amp?videocodec=h264 RTSP/1.0\r\n"
                "CSeq: 1\r\n\r\n".encode()
            )
            assert s.recv(4096).startswith(b"RTSP/1.0 415 ")
            s.close()
        finally:
            listener.close()


def test_a_reboot_drops_the_rtsp_connection(cam: SimulatedCamera) -> None:
    r = RawRtsp(cam)
    try:
        r.play()
        r.pump(0.5)
        cam.reboot(0.5)
        with pytest.raises((ConnectionError, OSError)):
            r.pump(5)
    finally:
        r.close()
    wait_until(lambda: not cam.rebooting, timeout=10, interval=0.1, raises=False)


def test_cli_rtsp_port_defaults_to_8554_or_a_free_one_with_a_free_http_port() -> None:
    from axis_ptz_ros2.sim.cli import _rtsp_port, build_parser  # noqa: PLC0415

    assert _rtsp_port(None, 8080) == 8554
    assert _rtsp_port(None, 0) == 0  # the demo starts the camera on --port 0: two demos must not collide
    assert _rtsp_port(-1, 8080) is None
    assert _rtsp_port(9554, 0) == 9554
    assert build_parser().parse_args(["--rtsp-port", "0"]).rtsp_port == 0


def test_the_pyav_reader_of_the_driver_plays_the_simulator(cam: SimulatedCamera) -> None:
    """The test oracle RtspReader (FFmpeg underneath): SPS/PPS from the SDP in front of every IDR, RTCP capture time."""
    from axis_ptz_ros2.vapix.rtsp import MediaStreamRequest  # noqa: PLC0415
    from tests.support.pyav_rtsp import RtspReader  # noqa: PLC0415

    assert cam.rtsp is not None
    url = MediaStreamRequest(resolution="640x360", fps=15, keyframe_interval=15).url(
        "127.0.0.1", cam.rtsp.port, "root", PASSWORD
    )
    aus = []
    with RtspReader(url, open_timeout_s=10, read_timeout_s=5, secrets=(PASSWORD,)) as reader:
        for au in reader.access_units():
            aus.append(au)
            if len(aus) >= 40:
                break
    keys = [au for au in aus if au.keyframe]
    assert len(keys) >= 2
    assert all(annexb.NalType.SPS in annexb.nal_types(au.data) for au in keys)
    offsets = [
        abs(au.capture_ns - stamp)
        for au in aus
        if au.capture_ns is not None and (stamp := annexb.extract_capture_stamp(au.data)) is not None
    ]
    assert offsets
    assert max(offsets) < 100_000_000


def test_a_camera_clock_offset_moves_the_sender_reports_not_the_sei_stamp(cam: SimulatedCamera) -> None:
    """``clock_offset_s`` (a camera without NTP): the sender reports' wall clock is 30 s behind the capture time
    in the SEI, which stays the true time."""
    cam.set_faults(clock_offset_s=-30.0)
    offsets = []
    try:
        with av.open(_url(cam), options=OPEN, timeout=(8, 5)) as c:
            stream = c.streams.video[0]
            deadline = time.monotonic() + 10
            for pkt in c.demux(stream):
                if time.monotonic() > deadline or len(offsets) >= 10:
                    break
                stamp = annexb.extract_capture_stamp(bytes(pkt)) if pkt.size else None
                if stamp is None or pkt.pts is None or not c.start_time_realtime:
                    continue
                capture_s = c.start_time_realtime / 1e6 + float(pkt.pts * stream.time_base)
                offsets.append(capture_s - stamp / 1e9)
    finally:
        cam.set_faults(clock_offset_s=0.0)
    assert len(offsets) >= 5, "no RTCP sender report or no capture-time SEI"
    assert max(abs(o + 30.0) for o in offsets) < 0.1, offsets
