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
- Capture time from the RTCP sender reports (NTP wall clock ↔ RTP time); every access unit also carries its
  arrival time and the latest report's RTP time and arrival (host clock), for
  :class:`~axis_ptz_ros2.streaming.clock_sync.StreamClock`.
- Open and read timeouts, a bounded queue of access units (the oldest is dropped when the consumer lags), keep-
  alive ``GET_PARAMETER`` at a third of the session timeout, typed errors (:mod:`~axis_ptz_ros2.vapix.errors`).
- Every request of the session is signed once the scheme is known (TEARDOWN and the keep-alive too), the Digest
  ``nc`` counted in the order the requests go out; a camera that offers only Basic to ``auth: auto`` is refused
  with the HTTP side's hint (set ``auth: basic``).
- What the camera cannot give us is said: an SDP without H.264 video (:class:`NoH264VideoError`, naming what it
  offers), a SETUP answered with UDP transport (:class:`UdpTransportError`).
- A lost IDR (a sequence gap inside or before it): no P-frame is handed out until the next IDR, and one is asked
  for (``Renew-Stream``, at most once a second). Before the session's first IDR, no P-frame either.
- A request from the server mid-stream (``OPTIONS``, ``GET_PARAMETER`` … as text between the ``$`` frames) is
  answered (``200 OK`` with its ``CSeq``; ``501`` for other methods); garbage between frames is skipped up to the
  next frame or message (:attr:`RtspClient.garbage_bytes`), at most :data:`MAX_MESSAGE` bytes of it in a row.
Credentials never reach a log line, a repr or an exception message.
"""

from __future__ import annotations

import collections
import contextlib
import re
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
    rtsp_auth_hint,
    sprop_parameter_sets,
)
from axis_ptz_ros2.vapix.rtsp_auth import RtspDigestAuth
from axis_ptz_ros2.vapix.rtsp_rtp import H264Depacketizer, RtpPacketError, SenderReportClock, parse_sender_report

MAX_QUEUE: Final = 8  #: access units held for a slow consumer (then the oldest is dropped)
MAX_MESSAGE: Final = 1 << 20
IDR_REQUEST_INTERVAL_S: Final = 1.0  #: Renew-Stream after a lost IDR at most this often
UDP_TRANSPORT: Final = "camera answered SETUP with UDP transport; only RTP over the RTSP TCP connection is supported"
_REQUEST_LINE: Final = re.compile(rb"([A-Z][A-Z_]{1,31}) (\S{1,2048}) RTSP/1\.0\r\n")
_REQUEST_START: Final = re.compile(rb"[A-Z][A-Z_]{0,31}( \S*( R?T?S?P?/?1?\.?0?\r?)?)?")
_RESYNC: Final = re.compile(rb"\$|RTSP/1\.0 |[A-Z][A-Z_]{1,31} \S{1,2048} RTSP/1\.0\r\n")
_STATIC_PAYLOADS: Final = {0: "PCMU/8000", 8: "PCMA/8000", 14: "MPA/90000", 26: "JPEG/90000", 32: "MPV/90000"}


class RtspUnsupportedError(ResponseParseError):
    """The camera answered, but with something this client cannot play (retrying does not help)."""


class NoH264VideoError(RtspUnsupportedError):
    """The SDP holds no H.264 video media (``m=video`` with ``a=rtpmap:<pt> H264/90000``); the message names
    what the camera offers."""


class UdpTransportError(RtspUnsupportedError):
    """The camera answered SETUP with UDP transport (no ``interleaved=``)."""


@dataclass(frozen=True, slots=True)
class ClientAccessUnit:
    """One access unit: Annex B (SPS/PPS in front of an IDR), RTP time, capture time on the camera's wall clock
    (None before an SR), arrival time on the host's wall clock (:func:`time.time_ns` when its last packet came)."""

    data: bytes
    keyframe: bool
    rtp_timestamp: int
    capture_ns: int | None
    arrival_ns: int | None = None
    report_rtp: int | None = None  #: the RTP time of the latest RTCP sender report (None before one)
    report_arrival_ns: int | None = None  #: … and when it arrived (host clock)


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
        self._sign_lock = threading.Lock()  # signing (Digest nc) and sending in one order
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
        self._rx_ns = 0  # host time the last chunk arrived
        self._report: tuple[int, int] | None = None  # (RTP time, arrival) of the latest sender report
        self._await_idr = True  # no P-frame before the session's first IDR, nor after a lost one
        self._idr_asked = -1e9
        self._stray = ""  # a reply nobody waits for (for the timeout message)
        self._garbage_run = 0  # garbage bytes skipped since the last good message
        self._session_url = self.url  #: the aggregate control URL (PLAY, SET_PARAMETER, keep-alive, TEARDOWN)
        self.session_id: str | None = None  #: the playing session's id (what SET_PARAMETER names)
        self.session_timeout_s = 60.0
        self.sdp = ""
        self.overflowed = 0  #: access units dropped because the consumer lagged
        self.refused = 0  #: access units refused (an IDR before any SPS/PPS is known, corrupt NAL units)
        self.held_back = 0  #: P-frames not handed out (before the first IDR, or after a lost one)
        self.idr_requests = 0  #: Renew-Stream sent after a lost IDR
        self.server_requests = 0  #: requests the server sent mid-stream (answered)
        self.garbage_bytes = 0  #: bytes skipped between messages
        self.background_errors = 0  #: keep-alives and Renew-Streams of the reader's own that failed
        self.last_background_error = ""
        self._pending: set[str] = set()  # methods of the reader's own requests under way

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
            control, payload_type = h264_media(self.sdp, f"RTSP DESCRIBE {self._where()}")
            self._params = annexb.ParameterSetTracker(sprop_parameter_sets(self.sdp))
            base = describe.headers.get("content-base", self.url)
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
            transport = setup.headers.get("transport", "")
            if _udp_transport(transport):
                raise UdpTransportError(f"RTSP SETUP {self._where()}: {UDP_TRANSPORT} (Transport: {transport[:80]})")
            self._channels = _interleaved_channels(transport)
            for item in rest.split(";"):
                k, _, v = item.strip().partition("=")
                if k.lower() == "timeout" and v.isdigit() and int(v) > 0:
                    self.session_timeout_s = float(v)
            play = self._call(
                "PLAY", self._session_url, {"Session": self.session_id, "Range": "npt=0.000-"}, deadline=deadline
            )
            self._depack = H264Depacketizer(payload_type, _rtp_info_seq(play.headers.get("rtp-info", "")))
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
                self._send_signed("TEARDOWN", self._session_url, {"Session": self.session_id}, b"", sock)
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
        """One request with the Digest negotiation; a non-2xx final status raises (401/403 with a hint)."""
        with self._sign_lock:
            self._auth.rtsp_uri = url
            flow = self._auth.auth_flow(httpx.Request(method, "http://rtsp.invalid/"))
            req = next(flow)
            cseq = self._send(method, url, {**headers, **_auth_header(req)}, body, self._sock)
        while True:
            resp = self._await(cseq, deadline, method)
            challenge = resp.headers.get("www-authenticate")
            fake = httpx.Response(
                resp.status, headers=[("WWW-Authenticate", challenge)] if challenge else [], request=req
            )
            with self._sign_lock:
                self._auth.rtsp_uri = url
                try:
                    req = flow.send(fake)
                except StopIteration:
                    break
                cseq = self._send(method, url, {**headers, **_auth_header(req)}, body, self._sock)
        hint = rtsp_auth_hint(self._auth, resp, req) if resp.status in (401, 403) else ""
        return check_rtsp_status(resp, f"RTSP {method} {self._where()}", hint)

    def _send_signed(
        self, method: str, url: str, headers: dict[str, str], body: bytes, sock: socket.socket | None
    ) -> int:
        """Send without waiting for the reply (TEARDOWN), signed as the session's requests are (nothing to sign
        with before a challenge was taken)."""
        with self._sign_lock:
            self._auth.rtsp_uri = url
            value = self._auth.preemptive(httpx.Request(method, "http://rtsp.invalid/"))
            return self._send(method, url, {**headers, **({"Authorization": value} if value else {})}, body, sock)

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
                        if self._closing.is_set():
                            raise CameraUnreachable(f"RTSP {method} {self._where()}: closed")
                        left = deadline - time.monotonic()
                        if left <= 0:
                            raise CameraTimeout(f"RTSP {method} {self._where()}: no reply in time{self._stray}")
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
                raise CameraTimeout(f"RTSP {what} {self._where()}: no data in time{self._stray}")
            try:
                ready, _, _ = select.select([sock], [], [], min(left, 0.5))
                chunk = sock.recv(65536) if ready else None
            except (OSError, ValueError) as err:
                raise CameraUnreachable(f"RTSP {what} {self._where()}: {type(err).__name__}") from err
            if chunk == b"":
                raise CameraUnreachable(f"RTSP {what} {self._where()}: the camera closed the connection")
            if chunk:
                self._rx_ns = time.time_ns()
                self._buf += chunk
                if len(self._buf) > 4 * MAX_MESSAGE:
                    raise ResponseParseError(f"RTSP {self._where()}: unparsable data piling up")

    def _take_message(self) -> bool:
        """Handle one message at the head of the buffer (or skip garbage); False if more bytes are needed."""
        buf = self._buf
        if not buf:
            return False
        if buf[0:1] == b"$":
            if not self._frame_start(buf, 0):
                self._skip_garbage()
                return True
            if len(buf) < 4:
                return False
            n = 4 + int.from_bytes(buf[2:4], "big")
            if len(buf) < n:
                return False
            self._buf = buf[n:]
            self._interleaved(buf[1], buf[4:n])
            return True
        if buf.startswith(b"RTSP/"[: len(buf)]):
            return self._take_reply(buf)
        line = _REQUEST_LINE.match(buf)
        if line is not None:
            return self._take_request(buf, line.group(1).decode("ascii"))
        if len(buf) < 64 and b"\n" not in buf and _REQUEST_START.fullmatch(buf):
            return False  # the start of a request line
        self._skip_garbage()
        return True

    def _frame_start(self, buf: bytes, pos: int) -> bool:
        """Whether a ``$`` at ``pos`` can start a frame of ours: one of our channels, an RTP/RTCP version 2."""
        if len(buf) > pos + 1 and buf[pos + 1] not in self._channels:
            return False
        return len(buf) <= pos + 4 or buf[pos + 4] >> 6 == 2

    def _skip_garbage(self) -> None:
        """Drop bytes up to the next thing that can start a frame or a message (at most MAX_MESSAGE in a row)."""
        buf = self._buf
        cut = max(1, len(buf) - 64)  # none: keep the tail (a start may be cut in two)
        for m in _RESYNC.finditer(buf, 1):
            if buf[m.start()] != 0x24 or self._frame_start(buf, m.start()):
                cut = m.start()
                break
        self._buf = buf[cut:]
        self._stray = f" (bytes that are no RTSP came instead, starting {buf[:12]!r})"
        self.garbage_bytes += cut
        self._garbage_run += cut
        if self._garbage_run > MAX_MESSAGE:
            raise ResponseParseError(f"RTSP {self._where()}: over {MAX_MESSAGE} bytes of garbage between messages")

    def _take_reply(self, buf: bytes) -> bool:
        end = buf.find(b"\r\n\r\n")
        if end < 0:
            if len(buf) > MAX_MESSAGE:
                raise ResponseParseError(f"RTSP {self._where()}: reply headers over {MAX_MESSAGE} bytes")
            return False
        head = parse_rtsp_response(buf[: end + 4])
        length = head.headers.get("content-length", "0")
        if not length.isascii() or not length.isdigit() or int(length) > MAX_MESSAGE:
            raise ResponseParseError(f"RTSP {self._where()}: Content-Length {length[:20]!r}")
        if len(buf) < end + 4 + int(length):
            return False
        body = buf[end + 4 : end + 4 + int(length)]
        self._buf = buf[end + 4 + int(length) :]
        self._garbage_run = 0
        cseq = head.headers.get("cseq", "")
        with self._cond:
            if cseq.isascii() and cseq.isdigit() and len(cseq) <= 9:
                self._replies[int(cseq)] = RtspResponse(head.status, head.reason, head.headers, body)
                while len(self._replies) > 16:
                    self._replies.pop(next(iter(self._replies)))
                if int(cseq) > self._cseq or int(cseq) <= 0:
                    self._stray = f" (a reply with CSeq {cseq} came, for no request of ours)"
            else:
                self._stray = f" (a {head.status} reply without a CSeq came)"
            self._cond.notify_all()
        return True

    def _take_request(self, buf: bytes, method: str) -> bool:
        """A request from the server (OPTIONS, GET_PARAMETER … mid-stream): answered, the stream goes on."""
        end = buf.find(b"\r\n\r\n")
        if end < 0:
            if len(buf) > MAX_MESSAGE:
                raise ResponseParseError(f"RTSP {self._where()}: request headers over {MAX_MESSAGE} bytes")
            return False
        headers: dict[str, str] = {}
        for raw in buf[:end].decode("latin-1").split("\r\n")[1:]:
            name, _, value = raw.partition(":")
            headers[name.strip().lower()] = value.strip()
        length = headers.get("content-length", "0")
        if not length.isascii() or not length.isdigit() or int(length) > MAX_MESSAGE:
            raise ResponseParseError(f"RTSP {self._where()}: Content-Length {length[:20]!r} in a server request")
        if len(buf) < end + 4 + int(length):
            return False
        self._buf = buf[end + 4 + int(length) :]
        self._garbage_run = 0
        self.server_requests += 1
        cseq = headers.get("cseq", "")
        status = "200 OK" if method in ("OPTIONS", "GET_PARAMETER") else "501 Not Implemented"
        lines = [f"RTSP/1.0 {status}"]
        if cseq.isascii() and cseq.isdigit() and len(cseq) <= 9:
            lines.append(f"CSeq: {cseq}")
        if self.session_id is not None:
            lines.append(f"Session: {self.session_id}")
        sock = self._sock
        if sock is not None:
            with self._wlock:
                try:
                    sock.sendall(("\r\n".join(lines) + "\r\n\r\n").encode("latin-1"))
                except OSError as err:
                    raise CameraUnreachable(f"RTSP {self._where()}: answering {method}: {type(err).__name__}") from err
        return True

    def _interleaved(self, channel: int, packet: bytes) -> None:
        self._garbage_run = 0
        if channel == self._channels[1]:
            with contextlib.suppress(RtpPacketError):
                report = parse_sender_report(packet)
                if report is not None:
                    self._clock.update(report)
                    self._report = (report.rtp_timestamp, self._rx_ns)
            return
        if channel != self._channels[0]:
            return
        lost = self._depack.dropped_idrs
        try:
            units = self._depack.push(packet)
        except RtpPacketError:
            return  # counted by the depacketiser; the access unit it belonged to is dropped
        finally:
            if self._depack.dropped_idrs != lost:
                self._lost_idr()
        for unit in units:
            assert self._params is not None
            try:
                data = self._params.process(unit.data)
                key = annexb.is_idr(data)
            except BitstreamError:
                self.refused += 1
                continue
            if self._await_idr and not key:
                self.held_back += 1  # undecodable without the IDR it refers to
                continue
            self._await_idr = False
            rtp, arrival = self._report if self._report is not None else (None, None)
            au = ClientAccessUnit(
                data, key, unit.timestamp, self._clock.unix_ns(unit.timestamp), self._rx_ns, rtp, arrival
            )
            with self._cond:
                if len(self._queue) == self._queue.maxlen:
                    self.overflowed += 1
                self._queue.append(au)
                self._cond.notify_all()

    def _lost_idr(self) -> None:
        """An IDR was lost: hold P-frames back until the next one, and ask for it (not more than once a second)."""
        self._await_idr = True
        now = time.monotonic()
        if self.session_id is None or now - self._idr_asked < IDR_REQUEST_INTERVAL_S:
            return
        self._idr_asked = now
        self.idr_requests += 1
        headers = {"Session": self.session_id, "Content-Type": "text/parameters"}
        self._background("SET_PARAMETER", headers, b"Renew-Stream: yes\r\n")

    def _background(self, method: str, headers: dict[str, str], body: bytes = b"") -> None:
        """A request of the reader's own (keep-alive, Renew-Stream) in a thread of its own, with the whole Digest
        negotiation (a nonce gone stale mid-session is renewed), never two of a method at once; it cannot end the
        stream: its failure is counted (:attr:`background_errors`, :attr:`last_background_error`)."""
        with self._cond:
            if method in self._pending:
                return
            self._pending.add(method)

        def run() -> None:
            try:
                self._call(method, self._session_url, headers, body, deadline=time.monotonic() + self._read_timeout_s)
            except Exception as err:  # noqa: BLE001 - a background request must never raise out of its thread
                if not self._closing.is_set():
                    self.background_errors += 1
                    self.last_background_error = str(err) if isinstance(err, AxisPtzError) else type(err).__name__
            finally:
                with self._cond:
                    self._pending.discard(method)

        threading.Thread(target=run, name=f"rtsp-client-{method.lower()}", daemon=True).start()

    def _read_loop(self) -> None:
        keepalive = time.monotonic() + self.session_timeout_s / 3
        try:
            while not self._closing.is_set():
                self._pump(time.monotonic() + self._read_timeout_s, "read")
                if time.monotonic() >= keepalive and self.session_id is not None:
                    self._background("GET_PARAMETER", {"Session": self.session_id})
                    keepalive = time.monotonic() + self.session_timeout_s / 3
        except AxisPtzError as err:
            self._fail(err)
        except Exception as err:  # noqa: BLE001 - a bug here must end the stream with a typed error, not hang it
            self._fail(ResponseParseError(f"RTSP {self._where()}: cannot read the stream ({type(err).__name__})"))

    def _fail(self, err: AxisPtzError) -> None:
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


def _udp_transport(transport: str) -> bool:
    """Whether a SETUP reply's ``Transport`` is UDP: no ``interleaved=``, and no ``/TCP`` profile (or ports)."""
    t = transport.lower().replace(" ", "")
    if not t or "interleaved=" in t:
        return False
    return not t.split(";")[0].endswith("/tcp") or "client_port=" in t or "server_port=" in t


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


def h264_media(sdp: str, where: str) -> tuple[str, int]:
    """``(a=control, payload type)`` of the first H.264 video media of an SDP (``m=video`` with
    ``a=rtpmap:<pt> H264/90000``); :class:`NoH264VideoError` naming what the SDP offers instead."""
    sections: list[tuple[str, list[str], dict[str, str], str]] = []  # (media, payload types, rtpmaps, control)
    for line in sdp.splitlines():
        line = line.strip()
        if line.startswith("m="):
            fields = line[2:].split()
            sections.append((fields[0] if fields else "?", fields[3:], {}, ""))
        elif sections and line.startswith("a=rtpmap:"):
            pt, _, encoding = line[len("a=rtpmap:") :].partition(" ")
            sections[-1][2][pt.strip()] = encoding.strip()
        elif sections and line.startswith("a=control:"):
            media, pts, maps, _ = sections[-1]
            sections[-1] = (media, pts, maps, line[len("a=control:") :].strip())
    offers = []
    for media, pts, maps, control in sections:
        for pt in pts:
            encoding = maps.get(pt, "")
            name, _, rate = encoding.partition("/")
            if media == "video" and name.upper() == "H264" and rate.split("/")[0] == "90000" and pt.isdigit():
                return control, int(pt) & 0x7F
        kinds = [maps.get(pt) or (_STATIC_PAYLOADS.get(int(pt), "") if pt.isdigit() else "") for pt in pts]
        what = " ".join(dict.fromkeys(k for k in kinds if k)) or ("payload " + ",".join(pts) if pts else "")
        note = " (event stream)" if media == "application" else ""
        offers.append(f"m={media}" + (f" {what}" if what else "") + note)
    offered = "; ".join(offers)[:300] if offers else "no media at all (an empty or non-SDP DESCRIBE answer)"
    raise NoH264VideoError(f"{where}: the camera offers no H.264 video: {offered}")


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
