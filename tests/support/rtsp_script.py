"""A raw RTSP server that plays scripted replies the way cameras do, for our RTSP client's tests (ROS-free).

:class:`ScriptedRtspServer` listens on loopback, one thread per connection, and answers DESCRIBE, SETUP, PLAY,
GET_PARAMETER, SET_PARAMETER and TEARDOWN as an Axis camera would, with what the test chose: the SDP, the
authentication (Digest with or without ``qop``, Basic only, none), the SETUP ``Transport`` answer, whether PLAY
carries ``RTP-Info``, the session timeout. After PLAY it runs the test's ``play(conn)`` in a thread of its own,
which writes whatever bytes the scenario needs (interleaved RTP/RTCP, server requests, garbage) while the
connection keeps answering the client.

It checks what a strict camera checks and records what it saw (:attr:`ScriptedRtspServer.requests`) and every
breach (:attr:`ScriptedRtspServer.problems`): a request without valid credentials once the client had them, a
Digest ``uri`` that is not the request's URL, an ``nc`` that does not grow, a reply to a server request without
its ``CSeq``.

:func:`encode_h264` makes a real H.264 stream with PyAV (libx264, baseline, no B-frames); :func:`rtp_frames`
packetises it with the simulator's packetiser (RFC 6184) and frames it for the RTSP connection.
"""

from __future__ import annotations

import base64
import contextlib
import hashlib
import secrets
import socket
import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from fractions import Fraction

import numpy as np

from axis_ptz_ros2.media import annexb
from axis_ptz_ros2.sim.rtsp.rtp import H264Packetizer, interleave, sender_report

REALM = "AXIS_ACCC8EF7DE6B"
CLOSE = b"\x00close"  #: an override's answer: close the connection instead of replying


@dataclass(frozen=True, slots=True)
class Request:
    """One request the client sent."""

    method: str
    uri: str
    headers: dict[str, str]  # lower-case names
    body: bytes

    def header(self, name: str) -> str:
        return self.headers.get(name.lower(), "")


@dataclass(frozen=True, slots=True)
class H264Stream:
    """Access units (Annex B, in-band SPS/PPS stripped unless asked to keep them), keyframe flags, SPS/PPS."""

    units: list[bytes]
    keyframes: list[bool]
    sps: bytes
    pps: bytes

    def sprop(self) -> str:
        return ",".join(base64.b64encode(n).decode() for n in (self.sps, self.pps))


def encode_h264(
    n: int, width: int = 160, height: int = 96, gop: int = 10, *, keep_parameter_sets: bool = False, seed: int = 0
) -> H264Stream:
    """``n`` frames of a moving pattern encoded with PyAV's libx264 (baseline, an IDR every ``gop`` frames)."""
    import av  # the tests that use it need PyAV anyway

    ctx = av.CodecContext.create("libx264", "w")
    ctx.width, ctx.height, ctx.pix_fmt = width, height, "yuv420p"
    ctx.time_base = Fraction(1, 30)
    ctx.framerate = Fraction(30, 1)
    ctx.profile = "baseline"
    ctx.options = {
        "preset": "ultrafast",
        "tune": "zerolatency",
        "x264-params": f"keyint={gop}:min-keyint={gop}:scenecut=0:bframes=0:repeat-headers=1",
    }
    rng = np.random.default_rng(seed)
    base = rng.integers(0, 255, (height, width, 3), dtype=np.uint8)
    units: list[bytes] = []
    keys: list[bool] = []
    sps = pps = b""
    for i in range(n):
        img = np.roll(base, 3 * i, axis=1)
        frame = av.VideoFrame.from_ndarray(img, format="rgb24").reformat(format="yuv420p")
        frame.pts = i
        for packet in ctx.encode(frame):
            data = bytes(packet)
            nals = annexb.split_nal_units(data)
            for nal in nals:
                if nal[0] & 0x1F == annexb.NalType.SPS:
                    sps = nal
                elif nal[0] & 0x1F == annexb.NalType.PPS:
                    pps = nal
            if not keep_parameter_sets:
                data = annexb.join_nal_units(n for n in nals if n[0] & 0x1F not in (7, 8))
            units.append(data)
            keys.append(packet.is_keyframe)
    for packet in ctx.encode(None):
        units.append(bytes(packet))
        keys.append(packet.is_keyframe)
    return H264Stream(units, keys, sps, pps)


def h264_sdp(stream: H264Stream, *, payload_type: int = 96, control: str = "trackID=1", extra: str = "") -> str:
    """An Axis-like SDP: one H.264 video media (``extra``: more media sections, in front of it)."""
    return (
        "v=0\r\no=- 1 1 IN IP4 127.0.0.1\r\ns=Session streamed with GStreamer\r\nt=0 0\r\na=control:*\r\n"
        + extra
        + f"m=video 0 RTP/AVP {payload_type}\r\nc=IN IP4 0.0.0.0\r\nb=AS:50000\r\n"
        + f"a=rtpmap:{payload_type} H264/90000\r\n"
        + f"a=fmtp:{payload_type} packetization-mode=1;profile-level-id=42c01e;"
        + f"sprop-parameter-sets={stream.sprop()}\r\n"
        + f"a=control:{control}\r\n"
    )


class RtpSender:
    """RTP packets of a stream on the 90 kHz clock from ``t0`` (30 fps), and sender reports."""

    def __init__(self, max_payload: int = 400, ssrc: int = 0x1234ABCD) -> None:
        self.packetizer = H264Packetizer(max_payload=max_payload, ssrc=ssrc)
        self.first_seq = self.packetizer.seq
        self.rtp0 = secrets.randbits(32)

    def packets(self, unit: bytes, index: int) -> list[bytes]:
        """The RTP packets of access unit ``index`` (unframed)."""
        return self.packetizer.packetize(unit, self.rtp0 + index * 3000)

    def framed(self, unit: bytes, index: int, channel: int = 0) -> bytes:
        return b"".join(interleave(channel, p) for p in self.packets(unit, index))

    def report(self, unix_ns: int, index: float, channel: int = 1) -> bytes:
        """A sender report saying RTP time of frame ``index`` is ``unix_ns`` on the camera's wall clock."""
        p = self.packetizer
        rtp = self.rtp0 + int(index * 3000)
        return interleave(channel, sender_report(p.ssrc, unix_ns, rtp, p.packets, p.octets, "scripted@test"))


class Conn:
    """One client connection (what ``play`` gets): :meth:`send` bytes; the requests it has seen."""

    def __init__(self, server: ScriptedRtspServer, sock: socket.socket) -> None:
        self.server = server
        self.sock = sock
        self.lock = threading.Lock()
        self.closed = threading.Event()
        self.stop = threading.Event()
        self.session = f"{secrets.randbits(40):X}"
        self.server_cseq = 100
        self.answers: list[tuple[str, dict[str, str]]] = []  # replies the client gave to our requests

    def send(self, data: bytes) -> bool:
        """Write; False once the client is gone."""
        with self.lock:
            try:
                self.sock.sendall(data)
                return True
            except OSError:
                self.closed.set()
                return False

    def request(self, method: str, uri: str = "*") -> None:
        """Send a request to the client (server → client, as some cameras do mid-stream)."""
        self.server_cseq += 1
        self.send(f"{method} {uri} RTSP/1.0\r\nCSeq: {self.server_cseq}\r\nSession: {self.session}\r\n\r\n".encode())

    def pace(self, seconds: float) -> bool:
        """Wait like a camera between frames; False if the stream is to end."""
        return not self.stop.wait(seconds) and not self.closed.is_set()


@dataclass
class Script:
    """What the server answers (defaults: an Axis camera with Digest and qop)."""

    sdp: str = ""
    auth: str = "digest"  # "digest", "digest-noqop", "basic", "none"
    username: str = "root"
    password: str = ""
    transport: Callable[[str], str] | None = None  # the SETUP request's Transport → the reply's (None: echo TCP)
    rtp_info: Callable[[Conn], str] | None = None  # the PLAY reply's RTP-Info (None: none)
    session_timeout: int = 60
    nonce_uses: int = 0  #: > 0: a Digest nonce serves this many requests, then is stale (a new challenge)
    play: Callable[[Conn], None] | None = None
    content_base: bool = True
    #: per method, a function that may replace the whole reply (raw bytes; b"": say nothing; CLOSE: close the
    #: connection; None: the normal reply)
    override: dict[str, Callable[[Request, int], bytes | None]] = field(default_factory=dict)


class ScriptedRtspServer:
    """See the module docstring. Use as a context manager; :attr:`port`."""

    def __init__(self, script: Script) -> None:
        self.script = script
        self.requests: list[Request] = []
        self.problems: list[str] = []
        self.conns: list[Conn] = []
        self._nonce = secrets.token_hex(16)
        self._nc_seen: dict[str, int] = {}
        self._nonce_used = 0
        self._stale: set[str] = set()
        self.stale_answers = 0  #: 401 stale=true sent
        self._authed = False  # the client has authenticated once: from then on every request must be signed
        self._listener = socket.create_server(("127.0.0.1", 0))
        self.port = self._listener.getsockname()[1]
        self._stopping = threading.Event()
        self._threads: list[threading.Thread] = []
        self._lock = threading.Lock()

    def __enter__(self) -> ScriptedRtspServer:
        t = threading.Thread(target=self._accept, name="scripted-rtsp", daemon=True)
        t.start()
        self._threads.append(t)
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        self._stopping.set()
        with contextlib.suppress(OSError):
            self._listener.close()
        for conn in list(self.conns):
            conn.stop.set()
            with contextlib.suppress(OSError):
                conn.sock.shutdown(socket.SHUT_RDWR)
            conn.sock.close()
        for t in self._threads:
            t.join(timeout=5)

    def methods(self) -> list[str]:
        with self._lock:
            return [r.method for r in self.requests]

    # ---- the connection ---------------------------------------------------------------------------------------
    def _accept(self) -> None:
        self._listener.settimeout(0.1)  # (a blocked accept() does not wake when the socket is closed)
        while not self._stopping.is_set():
            try:
                sock, _ = self._listener.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            sock.settimeout(None)
            conn = Conn(self, sock)
            self.conns.append(conn)
            t = threading.Thread(target=self._serve, args=(conn,), name="scripted-rtsp-conn", daemon=True)
            t.start()
            self._threads.append(t)

    def _serve(self, conn: Conn) -> None:
        buf = b""
        with contextlib.suppress(OSError):
            while not conn.stop.is_set():
                chunk = conn.sock.recv(65536)
                if not chunk:
                    break
                buf += chunk
                while True:
                    end = buf.find(b"\r\n\r\n")
                    if end < 0:
                        break
                    lines = buf[:end].decode("latin-1").split("\r\n")
                    headers = {}
                    for line in lines[1:]:
                        k, _, v = line.partition(":")
                        headers[k.strip().lower()] = v.strip()
                    length = int(headers.get("content-length", "0"))
                    if len(buf) < end + 4 + length:
                        break
                    body = buf[end + 4 : end + 4 + length]
                    buf = buf[end + 4 + length :]
                    first = lines[0].split(" ")
                    if first[0].startswith("RTSP/"):  # the client's answer to our request
                        conn.answers.append((lines[0], headers))
                        continue
                    req = Request(first[0], first[1] if len(first) > 1 else "", headers, body)
                    with self._lock:
                        self.requests.append(req)
                    self._answer(conn, req)
        conn.closed.set()
        conn.stop.set()

    def _answer(self, conn: Conn, req: Request) -> None:
        s = self.script
        cseq = int(req.header("cseq") or 0)
        override = s.override.get(req.method)
        if override is not None:
            raw = override(req, cseq)
            if raw is not None:
                if raw == CLOSE:
                    conn.sock.shutdown(socket.SHUT_RDWR)
                elif raw:
                    conn.send(raw)
                return
        verdict = self._check_auth(req)
        if verdict:
            stale = verdict == "stale nonce"
            self.stale_answers += stale
            challenges = [("WWW-Authenticate", c) for c in self._challenges(stale=stale)]
            conn.send(self._reply(401, cseq, challenges))
            return
        if req.method == "OPTIONS":
            conn.send(self._reply(200, cseq, [("Public", "DESCRIBE, SETUP, PLAY, TEARDOWN, GET_PARAMETER")]))
        elif req.method == "DESCRIBE":
            base = req.uri.split("?")[0] + "/"
            head = [("Content-Type", "application/sdp")] + ([("Content-Base", base)] if s.content_base else [])
            conn.send(self._reply(200, cseq, head, s.sdp.encode()))
        elif req.method == "SETUP":
            asked = req.header("transport")
            answer = s.transport(asked) if s.transport is not None else asked + ";ssrc=1234ABCD;mode=play"
            session = f"{conn.session};timeout={s.session_timeout}"
            conn.send(self._reply(200, cseq, [("Transport", answer), ("Session", session)]))
        elif req.method == "PLAY":
            head = [("Session", conn.session), ("Range", "npt=now-")]
            if s.rtp_info is not None:
                head.append(("RTP-Info", s.rtp_info(conn)))
            conn.send(self._reply(200, cseq, head))
            if s.play is not None:
                t = threading.Thread(target=self._play, args=(conn,), name="scripted-rtsp-play", daemon=True)
                t.start()
                self._threads.append(t)
        elif req.method in ("GET_PARAMETER", "SET_PARAMETER", "TEARDOWN"):
            if req.header("session").split(";")[0] != conn.session:
                conn.send(self._reply(454, cseq))
                return
            conn.send(self._reply(200, cseq, [("Session", conn.session)]))
            if req.method == "TEARDOWN":
                conn.stop.set()
        else:
            conn.send(self._reply(501, cseq))

    def _play(self, conn: Conn) -> None:
        assert self.script.play is not None
        with contextlib.suppress(OSError):
            self.script.play(conn)

    @staticmethod
    def _reply(status: int, cseq: int, headers: Iterable[tuple[str, str]] = (), body: bytes = b"") -> bytes:
        reasons = {200: "OK", 401: "Unauthorized", 454: "Session Not Found", 501: "Not Implemented"}
        lines = [f"RTSP/1.0 {status} {reasons.get(status, 'Error')}", f"CSeq: {cseq}"]
        lines.append(f"Date: {time.strftime('%a, %d %b %Y %H:%M:%S GMT', time.gmtime())}")
        lines += [f"{k}: {v}" for k, v in headers]
        if body:
            lines.append(f"Content-Length: {len(body)}")
        return ("\r\n".join(lines) + "\r\n\r\n").encode() + body

    # ---- authentication -------------------------------------------------------------------------------------
    def _challenges(self, *, stale: bool = False) -> list[str]:
        mode = self.script.auth
        if mode == "basic":
            return ['Basic realm="AXIS"']
        qop = ', qop="auth"' if mode == "digest" else ""
        return [
            f'Digest realm="{REALM}", nonce="{self._nonce}", algorithm=MD5{qop}' + (", stale=true" if stale else "")
        ]

    def _check_auth(self, req: Request) -> str:
        """ "" if the request may pass; else why not (recorded as a problem once the client had authenticated)."""
        s = self.script
        if s.auth == "none" or req.method == "OPTIONS":
            return ""
        with self._lock:
            why = self._why_not(req)
            if why and self._authed and why != "stale nonce":
                self.problems.append(f"{req.method}: {why}")
            if not why:
                self._authed = True
                if s.auth.startswith("digest") and s.nonce_uses:
                    self._nonce_used += 1
                    if self._nonce_used >= s.nonce_uses:  # the next request finds this nonce stale
                        self._stale.add(self._nonce)
                        self._nonce, self._nonce_used = secrets.token_hex(16), 0
            return why

    def _why_not(self, req: Request) -> str:
        s = self.script
        value = req.header("authorization")
        if not value:
            return "no Authorization"
        scheme, _, rest = value.partition(" ")
        if s.auth == "basic":
            token = base64.b64encode(f"{s.username}:{s.password}".encode()).decode()
            return "" if scheme == "Basic" and rest == token else "wrong Basic credentials"
        if scheme != "Digest":
            return f"{scheme} where Digest was asked for"
        p = _digest_params(rest)
        if p.get("uri") != req.uri:
            return f"Digest uri {p.get('uri')!r} is not the request's URL"
        if p.get("nonce") in self._stale:
            return "stale nonce"
        if p.get("nonce") != self._nonce or p.get("username") != s.username:
            return "wrong nonce or user"

        def h(text: str) -> str:
            return hashlib.md5(text.encode()).hexdigest()  # noqa: S324 - Digest MD5, as the cameras do

        ha1, ha2 = h(f"{s.username}:{REALM}:{s.password}"), h(f"{req.method}:{req.uri}")
        if s.auth == "digest":
            if p.get("qop") != "auth" or "nc" not in p or "cnonce" not in p:
                return "no qop=auth/nc/cnonce"
            nc = int(p["nc"], 16)
            if nc <= self._nc_seen.get(self._nonce, 0):
                self.problems.append(f"{req.method}: nc {nc} does not grow (last {self._nc_seen[self._nonce]})")
            self._nc_seen[self._nonce] = max(nc, self._nc_seen.get(self._nonce, 0))
            want = h(f"{ha1}:{self._nonce}:{p['nc']}:{p['cnonce']}:auth:{ha2}")
        else:
            if "qop" in p:
                return "qop where the challenge had none"
            want = h(f"{ha1}:{self._nonce}:{ha2}")
        return "" if p.get("response") == want else "wrong Digest response"


def _digest_params(text: str) -> dict[str, str]:
    out: dict[str, str] = {}
    for part in _split_commas(text):
        k, _, v = part.strip().partition("=")
        out[k.strip().lower()] = v.strip().strip('"')
    return out


def _split_commas(text: str) -> list[str]:
    parts, cur, quoted = [], "", False
    for ch in text:
        if ch == '"':
            quoted = not quoted
        if ch == "," and not quoted:
            parts.append(cur)
            cur = ""
        else:
            cur += ch
    return [*parts, cur]
