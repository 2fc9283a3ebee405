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
- What the camera cannot give us is said: an SDP without H.264 video (:class:`~.rtsp_sdp.NoH264VideoError`, naming what
  it offers), a SETUP answered with UDP transport (:class:`~.rtsp_sdp.UdpTransportError`).
- A lost IDR (a sequence gap inside or before it): no P-frame is handed out until the next IDR, and one is asked
  for (``Renew-Stream``, at most once a second). Before the session's first IDR, no P-frame either.
- A request from the server mid-stream (``OPTIONS``, ``GET_PARAMETER`` … as text between the ``$`` frames) is
  answered (``200 OK`` with its ``CSeq``; ``501`` for other methods); garbage between frames is skipped up to the
  next frame or message (:attr:`RtspClient.garbage_bytes`); both in :mod:`.rtsp_connection`.
Credentials never reach a log line, a repr or an exception message.
"""

from __future__ import annotations

import collections
import contextlib
import socket
import threading
import time
import urllib.parse
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
    MediaStreamRequest,
    RtspResponse,
    check_rtsp_status,
    rtsp_auth_hint,
    sprop_parameter_sets,
)
from axis_ptz_ros2.vapix.rtsp_auth import RtspDigestAuth
from axis_ptz_ros2.vapix.rtsp_connection import RtspConnection
from axis_ptz_ros2.vapix.rtsp_rtp import (
    H264Depacketizer,
    RtpAccessUnit,
    RtpPacketError,
    SenderReportClock,
    parse_sender_report,
)
from axis_ptz_ros2.vapix.rtsp_sdp import (
    UDP_TRANSPORT,
    UdpTransportError,
    h264_media,
    interleaved_channels,
    rtp_info_seq,
    sdp_control,
    udp_transport,
)

MAX_QUEUE: Final = 8  #: access units held for a slow consumer (then the oldest is dropped)
IDR_REQUEST_INTERVAL_S: Final = 1.0  #: Renew-Stream after a lost IDR at most this often


class RtspClient(RtspConnection):
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
        super().__init__(host, port, f"rtsp://{netloc}:{port}{path}" + (f"?{query}" if query else ""))
        self._auth = RtspDigestAuth(username, password, auth)
        self._open_timeout_s, self._read_timeout_s = open_timeout_s, read_timeout_s
        self._sign_lock = threading.Lock()  # signing (Digest nc) and sending in one order
        self._queue: collections.deque[RtpAccessUnit] = collections.deque(maxlen=max_queue)
        self._error: AxisPtzError | None = None
        self._reader: threading.Thread | None = None
        self._closing = threading.Event()
        self._depack = H264Depacketizer()
        self._clock = SenderReportClock()
        self._params: annexb.ParameterSetTracker | None = None
        self._report: tuple[int, int] | None = None  # (RTP time, arrival) of the latest sender report
        self._await_idr = True  # no P-frame before the session's first IDR, nor after a lost one
        self._idr_asked = -1e9
        self._session_url = self.url  #: the aggregate control URL (PLAY, SET_PARAMETER, keep-alive, TEARDOWN)
        self.session_timeout_s = 60.0
        self.sdp = ""
        self.overflowed = 0  #: access units dropped because the consumer lagged
        self.refused = 0  #: access units refused (an IDR before any SPS/PPS is known, corrupt NAL units)
        self.held_back = 0  #: P-frames not handed out (before the first IDR, or after a lost one)
        self.idr_requests = 0  #: Renew-Stream sent after a lost IDR
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
            aggregate = sdp_control(self.sdp, video=False)
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
            if udp_transport(transport):
                raise UdpTransportError(f"RTSP SETUP {self._where()}: {UDP_TRANSPORT} (Transport: {transport[:80]})")
            self._channels = interleaved_channels(transport)
            for item in rest.split(";"):
                k, _, v = item.strip().partition("=")
                if k.lower() == "timeout" and v.isdigit() and int(v) > 0:
                    self.session_timeout_s = float(v)
            play = self._call(
                "PLAY", self._session_url, {"Session": self.session_id, "Range": "npt=0.000-"}, deadline=deadline
            )
            self._depack = H264Depacketizer(payload_type, rtp_info_seq(play.headers.get("rtp-info", "")))
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
    def read(self, timeout_s: float | None = None) -> RtpAccessUnit:
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
            au = RtpAccessUnit(
                data, key, unit.rtp_timestamp, self._clock.unix_ns(unit.rtp_timestamp), self._rx_ns, rtp, arrival
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


def _auth_header(req: httpx.Request) -> dict[str, str]:
    value = req.headers.get("Authorization")
    return {"Authorization": value} if value else {}
