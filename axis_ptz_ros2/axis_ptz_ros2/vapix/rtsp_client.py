"""An RTSP/RTP client of our own for an Axis camera's H.264 stream: it owns the playing session (ROS-free).

Why ours and not only FFmpeg's (:class:`~axis_ptz_ros2.vapix.rtsp.RtspReader`): ``SET_PARAMETER`` (``Renew-Stream:
yes`` for an IDR now, ``Adjustable-Stream-Configuration`` for live fps/bitrate) acts on the *playing* session, and
PyAV does not expose the ``Session`` id of the session FFmpeg set up; a second session of our own gets its own
stream, not an IDR in the one we play. This client plays and controls on one RTSP connection.

- RTP and RTCP interleaved on the RTSP TCP connection (``RTP/AVP/TCP;unicast;interleaved=0-1``).
- Digest negotiated like the HTTP side (:class:`~axis_ptz_ros2.vapix.rtsp_auth.RtspDigestAuth`), signing the
  absolute request URL as RTSP clients do.
- RFC 6184 depacketising (:mod:`.rtsp_rtp`): FU-A, STAP-A, single NAL units; an access unit with a gap or a
  corrupt fragment is dropped whole, never passed on half.
- SPS/PPS from the SDP (``sprop-parameter-sets``) in front of every IDR (Axis sends them only in the SDP).
- Capture time from the RTCP sender reports (NTP wall clock ↔ RTP time).
- Open and read timeouts, a bounded queue of access units (the oldest is dropped when the consumer lags), keep-
  alive ``GET_PARAMETER`` at a third of the session timeout, typed errors (:mod:`~axis_ptz_ros2.vapix.errors`).
Credentials never reach a log line, a repr or an exception message.
"""

from __future__ import annotations

import collections
import contextlib
import select
import socket
import threading
import time
import urllib.parse
from dataclasses import dataclass
from typing import Final

import httpx

from axis_ptz_ros2.media import annexb
from axis_ptz_ros2.media.errors import BitstreamError
from axis_ptz_ros2.vapix.auth import AuthMode
from axis_ptz_ros2.vapix.errors import (
    AxisPtzError,
    CameraTimeout,
    CameraUnreachable,
    ResponseParseError,
)
from axis_ptz_ros2.vapix.rtsp import (
    MEDIA_PATH,
    USER_AGENT,
    MediaStreamRequest,
    RtspResponse,
    check_rtsp_status,
    parse_rtsp_response,
    sprop_parameter_sets,
)
from axis_ptz_ros2.vapix.rtsp_auth import RtspDigestAuth
from axis_ptz_ros2.vapix.rtsp_rtp import H264Depacketizer, RtpPacketError, SenderReportClock, parse_sender_report

MAX_QUEUE: Final = 8  #: access units held for a slow consumer (then the oldest is dropped)
MAX_MESSAGE: Final = 1 << 20


@dataclass(frozen=True, slots=True)
class ClientAccessUnit:
    """One access unit: Annex B (SPS/PPS in front of an IDR), RTP time, capture time (None before an SR)."""

    data: bytes
    keyframe: bool
    rtp_timestamp: int
    capture_ns: int | None


class RtspClient:
    """Play ``stream`` from ``host:port`` and own the session: :meth:`open`, :meth:`read`, :meth:`renew_stream`."""

    def __init__(
        self,
        host: str,
        port: int = 554,
        *,
        stream: MediaStreamRequest | None = None,
        path: str = MEDIA_PATH,
        username: str | None = None,
        password: str | None = None,
        auth: AuthMode | str = AuthMode.AUTO,
        open_timeout_s: float = 5.0,
        read_timeout_s: float = 3.0,
        max_queue: int = MAX_QUEUE,
    ) -> None:
        netloc = f"[{host}]" if ":" in host else host
        query = urllib.parse.urlencode((stream or MediaStreamRequest()).query())
        self.url = f"rtsp://{netloc}:{port}{path}" + (f"?{query}" if query else "")
        self._host, self._port = host, port
        self._auth = RtspDigestAuth(username, password, auth)
        self._open_timeout_s, self._read_timeout_s = open_timeout_s, read_timeout_s
        self._sock: socket.socket | None = None
        self._buf = b""
        self._cseq = 0
        self._wlock = threading.Lock()
        self._cond = threading.Condition()
        self._replies: dict[int, RtspResponse] = {}
        self._queue: collections.deque[ClientAccessUnit] = collections.deque(maxlen=max_queue)
        self._error: AxisPtzError | None = None
        self._reader: threading.Thread | None = None
        self._closing = threading.Event()
        self._depack = H264Depacketizer()
        self._clock = SenderReportClock()
        self._params: annexb.ParameterSetTracker | None = None
        self._channels = (0, 1)
        self._session_url = self.url  #: the aggregate control URL (PLAY, SET_PARAMETER, keep-alive, TEARDOWN)
        self.session_id: str | None = None  #: the playing session's id (what SET_PARAMETER names)
        self.session_timeout_s = 60.0
        self.sdp = ""
        self.overflowed = 0  #: access units dropped because the consumer lagged
        self.refused = 0  #: access units refused (an IDR before any SPS/PPS is known, corrupt NAL units)

    def __repr__(self) -> str:
        return f"RtspClient({self._host}:{self._port}, session={self.session_id!r})"

    @property
    def dropped(self) -> int:
        """Access units the depacketiser dropped (gap, corrupt fragment)."""
        return self._depack.dropped

    # ---- lifecycle ---------------------------------------------------------------------------------------------
    def open(self) -> None:
        """Connect, DESCRIBE, SETUP (interleaved TCP), PLAY; then read in a thread of its own."""
        deadline = time.monotonic() + self._open_timeout_s
        try:
            self._sock = socket.create_connection((self._host, self._port), timeout=self._open_timeout_s)
            describe = self._call("DESCRIBE", self.url, {"Accept": "application/sdp"}, deadline=deadline)
            self.sdp = describe.body.decode("utf-8", "replace")
            self._params = annexb.ParameterSetTracker(sprop_parameter_sets(self.sdp))
            base = describe.headers.get("content-base", self.url)
            control = _control(self.sdp, video=True)
            aggregate = _control(self.sdp, video=False)
            if aggregate in ("", "*"):
                self._session_url = base
            else:
                self._session_url = aggregate if "://" in aggregate else urllib.parse.urljoin(base, aggregate)
            setup_url = control if "://" in control else urllib.parse.urljoin(base, control) if control else self.url
            setup = self._call(
                "SETUP", setup_url, {"Transport": "RTP/AVP/TCP;unicast;interleaved=0-1"}, deadline=deadline
            )
            sid, _, rest = setup.headers.get("session", "").partition(";")
            if not sid.strip():
                raise ResponseParseError(f"RTSP SETUP {self._where()}: no Session header in the reply")
            self.session_id = sid.strip()
            self._channels = _interleaved_channels(setup.headers.get("transport", ""))
            for item in rest.split(";"):
                k, _, v = item.strip().partition("=")
                if k.lower() == "timeout" and v.isdigit() and int(v) > 0:
                    self.session_timeout_s = float(v)
            play = self._call(
                "PLAY", self._session_url, {"Session": self.session_id, "Range": "npt=0.000-"}, deadline=deadline
            )
            self._depack = H264Depacketizer(first_seq=_rtp_info_seq(play.headers.get("rtp-info", "")))
        except BaseException:
            self.close()
            raise
        self._reader = threading.Thread(target=self._read_loop, name="rtsp-client", daemon=True)
        self._reader.start()

    def close(self) -> None:
        """TEARDOWN (best effort) and close."""
        self._closing.set()
        sock, self._sock = self._sock, None
        if sock is None:
            return
        if self.session_id is not None:
            with contextlib.suppress(OSError, AxisPtzError):
                self._send("TEARDOWN", self._session_url, {"Session": self.session_id}, b"", sock)
        with contextlib.suppress(OSError):
            sock.shutdown(socket.SHUT_RDWR)
        sock.close()
        if self._reader is not None and self._reader is not threading.current_thread():
            self._reader.join(timeout=2.0)
        with self._cond:
            self._cond.notify_all()

    def __enter__(self) -> RtspClient:
        self.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ---- the stream ---------------------------------------------------------------------------------------------
    def read(self, timeout_s: float | None = None) -> ClientAccessUnit:
        """The next access unit; :class:`CameraTimeout` if none within ``timeout_s`` (default: the read timeout),
        the reader's error (:class:`CameraUnreachable` …) once the connection is gone."""
        deadline = time.monotonic() + (self._read_timeout_s if timeout_s is None else timeout_s)
        with self._cond:
            while not self._queue:
                if self._error is not None:
                    raise self._error
                if self._closing.is_set():
                    raise CameraUnreachable(f"RTSP {self._where()}: closed")
                left = deadline - time.monotonic()
                if left <= 0:
                    raise CameraTimeout(f"RTSP {self._where()}: no access unit within {self._read_timeout_s} s")
                self._cond.wait(left)
            return self._queue.popleft()

    def renew_stream(self) -> RtspResponse:
        """``SET_PARAMETER`` ``Renew-Stream: yes`` on the playing session: its next frame is an IDR."""
        return self.set_parameter(b"Renew-Stream: yes\r\n")

    def adjust_stream(self, *, fps: int | None = None, max_bitrate_kbps: int | None = None) -> RtspResponse:
        """``Adjustable-Stream-Configuration`` (streams opened with ``adjustablelivestream=1``)."""
        items = [f"fps={fps}"] if fps is not None else []
        if max_bitrate_kbps is not None:
            items.append(f"videomaxbitrate={max_bitrate_kbps}")
        MediaStreamRequest(fps=fps or 30, max_bitrate_kbps=max_bitrate_kbps or 1000)  # validates
        return self.set_parameter(f"Adjustable-Stream-Configuration: {','.join(items)}\r\n".encode())

    def set_parameter(self, body: bytes) -> RtspResponse:
        """``SET_PARAMETER`` on the playing session (the reply arrives through the reader thread)."""
        if self.session_id is None or self._reader is None:
            raise CameraUnreachable("RTSP SET_PARAMETER before open()")
        headers = {"Session": self.session_id, "Content-Type": "text/parameters"}
        return self._call(
            "SET_PARAMETER", self._session_url, headers, body, deadline=time.monotonic() + self._read_timeout_s
        )

    # ---- requests ------------------------------------------------------------------------------------------------
    def _call(
        self, method: str, url: str, headers: dict[str, str], body: bytes = b"", *, deadline: float
    ) -> RtspResponse:
        """One request with the Digest negotiation; a non-2xx final status raises."""
        self._auth.rtsp_uri = url
        flow = self._auth.auth_flow(httpx.Request(method, "http://rtsp.invalid/"))
        req = next(flow)
        while True:
            cseq = self._send(method, url, {**headers, **_auth_header(req)}, body, self._sock)
            resp = self._await(cseq, deadline, method)
            challenge = resp.headers.get("www-authenticate")
            fake = httpx.Response(
                resp.status, headers=[("WWW-Authenticate", challenge)] if challenge else [], request=req
            )
            try:
                req = flow.send(fake)
            except StopIteration:
                break
        return check_rtsp_status(resp, f"RTSP {method} {self._where()}")

    def _send(self, method: str, url: str, headers: dict[str, str], body: bytes, sock: socket.socket | None) -> int:
        if sock is None:
            raise CameraUnreachable(f"RTSP {method} {self._where()}: not connected")
        with self._wlock:
            self._cseq += 1
            lines = [f"{method} {url} RTSP/1.0", f"CSeq: {self._cseq}", f"User-Agent: {USER_AGENT}"]
            lines += [f"{k}: {v}" for k, v in headers.items()]
            if body:
                lines.append(f"Content-Length: {len(body)}")
            try:
                sock.sendall(("\r\n".join(lines) + "\r\n\r\n").encode("latin-1") + body)
            except OSError as err:
                raise CameraUnreachable(f"RTSP {method} {self._where()}: {type(err).__name__}") from err
            return self._cseq

    def _await(self, cseq: int, deadline: float, method: str) -> RtspResponse:
        """The reply to request ``cseq``: read here before PLAY, delivered by the reader thread after."""
        while True:
            if self._reader is not None:
                with self._cond:
                    while cseq not in self._replies:
                        if self._error is not None:
                            raise self._error
                        left = deadline - time.monotonic()
                        if left <= 0:
                            raise CameraTimeout(f"RTSP {method} {self._where()}: no reply in time")
                        self._cond.wait(left)
                    return self._replies.pop(cseq)
            if cseq in self._replies:
                return self._replies.pop(cseq)
            self._pump(deadline, method)

    def _pump(self, deadline: float, what: str) -> None:
        """Read from the socket until one more message is handled (or raise)."""
        sock = self._sock
        if sock is None:
            raise CameraUnreachable(f"RTSP {what} {self._where()}: closed")
        while True:
            if self._take_message():
                return
            left = deadline - time.monotonic()
            if left <= 0:
                raise CameraTimeout(f"RTSP {what} {self._where()}: no data in time")
            try:
                ready, _, _ = select.select([sock], [], [], min(left, 0.5))
                chunk = sock.recv(65536) if ready else None
            except (OSError, ValueError) as err:
                raise CameraUnreachable(f"RTSP {what} {self._where()}: {type(err).__name__}") from err
            if chunk == b"":
                raise CameraUnreachable(f"RTSP {what} {self._where()}: the camera closed the connection")
            if chunk:
                self._buf += chunk
                if len(self._buf) > 4 * MAX_MESSAGE:
                    raise ResponseParseError(f"RTSP {self._where()}: unparsable data piling up")

    def _take_message(self) -> bool:
        """Handle one complete message at the head of the buffer; False if more bytes are needed."""
        buf = self._buf
        if not buf:
            return False
        if buf[0:1] == b"$":
            if len(buf) < 4:
                return False
            n = 4 + int.from_bytes(buf[2:4], "big")
            if len(buf) < n:
                return False
            self._buf = buf[n:]
            self._interleaved(buf[1], buf[4:n])
            return True
        if not buf.startswith(b"RTSP/"[: len(buf)]):
            raise ResponseParseError(f"RTSP {self._where()}: garbage between messages ({buf[:16]!r})")
        end = buf.find(b"\r\n\r\n")
        if end < 0:
            if len(buf) > MAX_MESSAGE:
                raise ResponseParseError(f"RTSP {self._where()}: reply headers over {MAX_MESSAGE} bytes")
            return False
        head = parse_rtsp_response(buf[: end + 4])
        length = head.headers.get("content-length", "0")
        if not length.isdigit() or int(length) > MAX_MESSAGE:
            raise ResponseParseError(f"RTSP {self._where()}: Content-Length {length[:20]!r}")
        if len(buf) < end + 4 + int(length):
            return False
        body = buf[end + 4 : end + 4 + int(length)]
        self._buf = buf[end + 4 + int(length) :]
        cseq = head.headers.get("cseq", "")
        with self._cond:
            if cseq.isdigit():
                self._replies[int(cseq)] = RtspResponse(head.status, head.reason, head.headers, body)
                while len(self._replies) > 16:
                    self._replies.pop(next(iter(self._replies)))
            self._cond.notify_all()
        return True

    def _interleaved(self, channel: int, packet: bytes) -> None:
        if channel == self._channels[1]:
            with contextlib.suppress(RtpPacketError):
                report = parse_sender_report(packet)
                if report is not None:
                    self._clock.update(report)
            return
        if channel != self._channels[0]:
            return
        try:
            units = self._depack.push(packet)
        except RtpPacketError:
            return  # counted by the depacketiser; the access unit it belonged to is dropped
        for unit in units:
            assert self._params is not None
            try:
                data = self._params.process(unit.data)
                key = annexb.is_idr(data)
            except BitstreamError:
                self.refused += 1
                continue
            au = ClientAccessUnit(data, key, unit.timestamp, self._clock.unix_ns(unit.timestamp))
            with self._cond:
                if len(self._queue) == self._queue.maxlen:
                    self.overflowed += 1
                self._queue.append(au)
                self._cond.notify_all()

    def _read_loop(self) -> None:
        keepalive = time.monotonic() + self.session_timeout_s / 3
        try:
            while not self._closing.is_set():
                self._pump(time.monotonic() + self._read_timeout_s, "read")
                if time.monotonic() >= keepalive and self.session_id is not None:
                    self._send("GET_PARAMETER", self._session_url, {"Session": self.session_id}, b"", self._sock)
                    keepalive = time.monotonic() + self.session_timeout_s / 3
        except AxisPtzError as err:
            if not self._closing.is_set():
                with self._cond:
                    self._error = err
                    self._cond.notify_all()

    def _where(self) -> str:
        return f"{self._host}:{self._port}{urllib.parse.urlsplit(self.url).path}"


def _auth_header(req: httpx.Request) -> dict[str, str]:
    value = req.headers.get("Authorization")
    return {"Authorization": value} if value else {}


def _rtp_info_seq(rtp_info: str) -> int | None:
    """``seq=`` of the first stream in an ``RTP-Info`` header (None if absent)."""
    for item in rtp_info.split(",")[0].split(";"):
        k, _, v = item.strip().partition("=")
        if k.lower() == "seq" and v.isascii() and v.isdigit() and len(v) <= 5 and int(v) <= 0xFFFF:
            return int(v)  # a 16-bit sequence number; anything else is not one (and is not wrapped into one)
    return None


def _interleaved_channels(transport: str) -> tuple[int, int]:
    """The RTP and RTCP channels the server chose (``interleaved=a-b``; default 0-1)."""
    for item in transport.split(";"):
        k, _, v = item.strip().partition("=")
        a, _, b = v.partition("-")
        if k.lower() == "interleaved":
            rtp = int(a) if a.isascii() and a.isdigit() and len(a) <= 3 else -1
            rtcp = (int(b) if b.isascii() and b.isdigit() and len(b) <= 3 else -1) if b else rtp + 1
            if not (0 <= rtp <= 255 and 0 <= rtcp <= 255):  # one byte in the '$' framing (RFC 2326 §10.12)
                raise ResponseParseError(f"Transport: interleaved={v[:20]!r} is not a channel pair in 0..255")
            return rtp, rtcp
    return 0, 1


def _control(sdp: str, *, video: bool) -> str:
    """The ``a=control`` of the first video media section (``video``) or of the session ("" if none)."""
    section = "session"
    for line in sdp.splitlines():
        if line.startswith("m="):
            if section == "video" or not video:
                break
            section = "video" if line.startswith("m=video") else "other"
        elif line.startswith("a=control:") and section == ("video" if video else "session"):
            return line[len("a=control:") :].strip()
    return ""
