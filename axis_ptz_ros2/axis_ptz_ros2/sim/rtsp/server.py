"""The simulated camera's RTSP server (RFC 2326, VAPIX RTSP API), one of its listeners (ROS-free, stdlib sockets).

Serves ``rtsp://host:port/axis-media/media.amp?videocodec=h264&…`` (arguments: :mod:`.media`): OPTIONS,
DESCRIBE (SDP with ``sprop-parameter-sets`` and ``profile-level-id``), SETUP (RTP over the RTSP TCP connection,
``RTP/AVP/TCP;interleaved=0-1``; UDP is refused with 461), PLAY, TEARDOWN, GET_PARAMETER (keep-alive) and
SET_PARAMETER (``Renew-Stream: yes`` → the next frame is an IDR; ``Adjustable-Stream-Configuration:
fps=…,videomaxbitrate=…`` on a stream opened with ``adjustablelivestream=1``). Digest/Basic exactly as the HTTP
side (the camera's :class:`~axis_ptz_ros2.sim.digest.CameraAuth`: same realm, nonces and challenge style); OPTIONS
needs none. A session without a keep-alive (any request naming it, or RTCP from the client) for ``timeout``
seconds (``Session: <id>;timeout=<s>``) ends and its connection closes. Reboots close every connection (or mute
them, for a packet-dropping reboot), as on the HTTP side.
"""

from __future__ import annotations

import contextlib
import email.utils
import select
import socket
import threading
import time
import urllib.parse
from dataclasses import dataclass, field

from axis_ptz_ros2.media import annexb
from axis_ptz_ros2.sim.frames import MAX_FPS
from axis_ptz_ros2.sim.rtsp.media import MEDIA_PATH, MediaError, MediaRequest, parameter_sets, parse_media_args, sdp
from axis_ptz_ros2.sim.rtsp.session import RtspSession, StreamClosedError
from axis_ptz_ros2.sim.view import CameraView

DEFAULT_SESSION_TIMEOUT_S = 60.0  #: what Axis cameras announce (h264.md)
MAX_REQUEST_BYTES = 16384
REASONS = {
    200: "OK",
    400: "Bad Request",
    401: "Unauthorized",
    404: "Not Found",
    405: "Method Not Allowed",
    415: "Unsupported Media Type",
    451: "Parameter Not Understood",
    454: "Session Not Found",
    455: "Method Not Valid in This State",
    461: "Unsupported Transport",
    501: "Not Implemented",
    503: "Service Unavailable",
}
METHODS = ("OPTIONS", "DESCRIBE", "SETUP", "PLAY", "TEARDOWN", "GET_PARAMETER", "SET_PARAMETER")


@dataclass
class _Request:
    method: str
    uri: str
    headers: dict[str, str]
    body: bytes

    def header(self, name: str) -> str | None:
        return self.headers.get(name.lower())


@dataclass
class _Response:
    status: int
    headers: list[tuple[str, str]] = field(default_factory=list)
    body: bytes = b""


class RtspListener:
    """The camera's RTSP server on ``host:port`` (port 0: any free one, kept across reopenings)."""

    def __init__(
        self, camera: CameraView, host: str, port: int, session_timeout_s: float = DEFAULT_SESSION_TIMEOUT_S
    ) -> None:
        """Not listening yet: :meth:`open`."""
        if not session_timeout_s > 0:
            raise ValueError("session_timeout_s must be > 0")
        self.camera = camera
        self.host = host
        self._port = port
        self.session_timeout_s = session_timeout_s
        self._sock: socket.socket | None = None
        self._conns: set[_Connection] = set()
        self._lock = threading.Lock()
        self._params: dict[MediaRequest, annexb.ParameterSets] = {}

    @property
    def port(self) -> int:
        """The TCP port (the real one after binding port 0)."""
        return self._port

    def url(self, query: str = "videocodec=h264") -> str:
        """``rtsp://host:port/axis-media/media.amp?<query>`` (no credentials)."""
        return f"rtsp://{self.host}:{self.port}{MEDIA_PATH}" + (f"?{query}" if query else "")

    @property
    def sessions(self) -> list[RtspSession]:
        """The live sessions (a snapshot)."""
        with self._lock:
            return [s for c in self._conns for s in c.sessions.values()]

    def open(self) -> None:
        """Bind and accept in a thread."""
        if self._sock is not None:
            return
        family = socket.AF_INET6 if ":" in self.host else socket.AF_INET
        sock = socket.socket(family, socket.SOCK_STREAM)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            sock.bind((self.host, self._port))
            sock.listen(16)
        except OSError:
            sock.close()
            raise
        self._port = sock.getsockname()[1]
        self._sock = sock
        threading.Thread(target=self._accept, args=(sock,), name="rtsp-accept", daemon=True).start()

    def close(self, silently: bool = False) -> None:
        """Stop listening; end every session; close every connection (``silently``: leave them open, mute)."""
        sock, self._sock = self._sock, None
        if sock is not None:
            with contextlib.suppress(OSError):
                sock.shutdown(socket.SHUT_RDWR)
            sock.close()
        with self._lock:
            conns = list(self._conns)
        for c in conns:
            c.end(silently)

    def parameter_sets(self, request: MediaRequest) -> annexb.ParameterSets:
        """SPS/PPS for a stream configuration (made once per configuration)."""
        with self._lock:
            known = self._params.get(request)
        if known is None:
            known = parameter_sets(request)
            with self._lock:
                self._params[request] = known
        return known

    def _accept(self, sock: socket.socket) -> None:
        while True:
            try:
                conn, addr = sock.accept()
            except OSError:
                return
            c = _Connection(self, conn, addr)
            with self._lock:
                self._conns.add(c)
            threading.Thread(target=c.run, name="rtsp-conn", daemon=True).start()

    def find(self, sid: str) -> RtspSession | None:
        """The live session ``sid`` on any connection (RTSP sessions are not tied to one connection)."""
        with self._lock:
            conns = list(self._conns)
        for c in conns:
            s = c.sessions.get(sid)
            if s is not None:
                return s
        return None

    def drop(self, sid: str) -> None:
        """Forget session ``sid`` (TEARDOWN, from any connection)."""
        with self._lock:
            conns = list(self._conns)
        for c in conns:
            c.sessions.pop(sid, None)

    def _forget(self, conn: _Connection) -> None:
        with self._lock:
            self._conns.discard(conn)


class _Connection:
    """One RTSP TCP connection: requests in, replies and interleaved RTP/RTCP out."""

    def __init__(self, listener: RtspListener, sock: socket.socket, addr: object) -> None:
        self.listener = listener
        self.cam = listener.camera
        self.sock = sock
        self.sessions: dict[str, RtspSession] = {}
        self._described: MediaRequest | None = None
        self._wlock = threading.Lock()
        self._closed = threading.Event()
        self._muted = False
        sock.settimeout(5.0)  # for sends: a client that stops reading for this long is dropped

    # ---- lifecycle ---------------------------------------------------------------------------------------
    def send(self, data: bytes) -> None:
        """Write to the client (thread-safe); raises :class:`StreamClosedError` once it cannot."""
        if self._muted or self._closed.is_set():
            raise StreamClosedError
        with self._wlock:
            try:
                self.sock.sendall(data)
            except OSError as err:
                self._closed.set()
                raise StreamClosedError from err

    def end(self, silently: bool = False) -> None:
        """End every session and close (``silently``: keep the socket open and say nothing more)."""
        for s in list(self.sessions.values()):
            s.stop()
        if silently:
            self._muted = True
            return
        self._closed.set()
        with contextlib.suppress(OSError):
            self.sock.shutdown(socket.SHUT_RDWR)

    def run(self) -> None:
        buf = b""
        try:
            while not self._closed.is_set():
                if self._muted:
                    if not self.cam.blackholed:
                        break  # the packet-dropping reboot is over: the peer learns with a reset
                    time.sleep(0.05)
                    continue
                for sid, s in list(self.sessions.items()):
                    if s.expired():
                        s.stop()
                        del self.sessions[sid]
                        return  # a camera drops the connection of a timed-out session
                try:
                    readable, _, _ = select.select([self.sock], [], [], 0.2)
                    if not readable:
                        continue
                    chunk = self.sock.recv(65536)
                except (OSError, ValueError):
                    return
                if not chunk:
                    return
                buf += chunk
                buf = self._consume(buf)
        except StreamClosedError:
            pass
        finally:
            for s in self.sessions.values():
                s.stop()
            if not self._muted or not self.cam.blackholed:
                with contextlib.suppress(OSError):
                    self.sock.close()
            self.listener._forget(self)  # noqa: SLF001

    def _consume(self, buf: bytes) -> bytes:
        """Handle every complete message in ``buf``; return what is left."""
        while buf:
            if buf[0:1] == b"$":  # interleaved RTCP from the client (receiver reports): a keep-alive
                if len(buf) < 4:
                    return buf
                n = 4 + int.from_bytes(buf[2:4], "big")
                if len(buf) < n:
                    return buf
                buf = buf[n:]
                for s in self.sessions.values():
                    s.touch()
                continue
            end = buf.find(b"\r\n\r\n")
            if end < 0:
                if len(buf) > MAX_REQUEST_BYTES:
                    self.send(b"RTSP/1.0 400 Bad Request\r\n\r\n")
                    self._closed.set()
                    return b""
                return buf
            head = buf[:end].decode("utf-8", "replace").split("\r\n")
            headers: dict[str, str] = {}
            for line in head[1:]:
                k, sep, v = line.partition(":")
                if sep:
                    headers[k.strip().lower()] = v.strip()
            try:
                length = int(headers.get("content-length", "0"))
            except ValueError:
                length = -1
            if not 0 <= length <= MAX_REQUEST_BYTES:
                self.send(b"RTSP/1.0 400 Bad Request\r\n\r\n")
                self._closed.set()
                return b""
            if len(buf) < end + 4 + length:
                return buf
            body = buf[end + 4 : end + 4 + length]
            buf = buf[end + 4 + length :]
            parts = head[0].split(" ")
            if len(parts) != 3 or not parts[2].startswith("RTSP/"):
                self.send(b"RTSP/1.0 400 Bad Request\r\n\r\n")
                continue
            self._answer(_Request(parts[0].upper(), parts[1], headers, body))
        return buf

    # ---- requests ------------------------------------------------------------------------------------------
    def _answer(self, req: _Request) -> None:
        sid = (req.header("Session") or "").split(";")[0].strip()
        found = self.listener.find(sid) if sid else None
        if found is not None:
            found.touch()
        resp = _Response(503) if self.cam.serving_errors() else self._dispatch(req, sid)
        lines = [f"RTSP/1.0 {resp.status} {REASONS.get(resp.status, 'Error')}", f"CSeq: {req.header('CSeq') or 0}"]
        lines.append(f"Date: {email.utils.formatdate(usegmt=True)}")
        lines += [f"{k}: {v}" for k, v in resp.headers]
        if resp.body:
            lines.append(f"Content-Length: {len(resp.body)}")
        self.send(("\r\n".join(lines) + "\r\n\r\n").encode() + resp.body)
        if req.method == "PLAY" and resp.status == 200:
            found = self.listener.find(sid)
            if found is not None:
                found.play()  # after the reply: no RTP before the PLAY response

    def _dispatch(self, req: _Request, sid: str) -> _Response:
        if req.method not in METHODS:
            return _Response(501 if req.method.isalpha() or "_" in req.method else 400)
        if req.method == "OPTIONS":
            return _Response(200, [("Public", ", ".join(METHODS))])
        url = urllib.parse.urlsplit(req.uri)
        path = url.path
        if path != MEDIA_PATH and not path.startswith(MEDIA_PATH + "/"):
            return _Response(404)
        verdict = self.cam.auth_result(req.header("Authorization"), req.method, req.uri)
        if verdict != "ok":
            return _Response(401, [("WWW-Authenticate", c) for c in self.cam.challenges(stale=verdict == "stale")])
        if req.method in ("PLAY", "TEARDOWN", "GET_PARAMETER", "SET_PARAMETER") and self.listener.find(sid) is None:
            if req.method == "GET_PARAMETER" and not sid:
                return _Response(200)
            return _Response(454)
        handler = getattr(self, "_" + req.method.lower())
        result: _Response = handler(req, url, sid)
        return result

    def _session(self, sid: str) -> RtspSession:
        session = self.listener.find(sid)
        if session is None:
            raise StreamClosedError  # torn down between the check and now: nothing sensible to answer
        return session

    def _media(self, url: urllib.parse.SplitResult) -> MediaRequest:
        args = urllib.parse.parse_qsl(url.query, keep_blank_values=True)
        if not args and self._described is not None:
            return self._described
        return parse_media_args(self.cam, args)

    def _describe(self, req: _Request, url: urllib.parse.SplitResult, sid: str) -> _Response:
        try:
            media = self._media(url)
        except MediaError as err:
            return _Response(err.status)
        self._described = media
        params = self.listener.parameter_sets(media)
        base = f"rtsp://{url.netloc}{MEDIA_PATH}"
        body = sdp(media, params, self.listener.host, base, url.query, int(time.time())).encode()
        return _Response(200, [("Content-Type", "application/sdp"), ("Content-Base", base + "/")], body)

    def _setup(self, req: _Request, url: urllib.parse.SplitResult, sid: str) -> _Response:
        transport = req.header("Transport") or ""
        spec = next((t for t in transport.split(",") if "RTP/AVP/TCP" in t.upper()), None)
        if spec is None:
            return _Response(461)  # only RTP over the RTSP connection here (a real camera also does UDP)
        channels = (0, 1)
        for item in spec.split(";"):
            k, _, v = item.strip().partition("=")
            if k.lower() == "interleaved":
                a, _, b = v.partition("-")
                if not (a.isdigit() and (not b or b.isdigit())) or int(a) > 254:
                    return _Response(461)
                channels = (int(a), int(b) if b else int(a) + 1)
        if sid and sid in self.sessions:
            session = self.sessions[sid]
        elif sid:
            return _Response(454)  # SETUP of an existing session: only on the connection that carries its RTP
        else:
            try:
                media = self._media(url)
            except MediaError as err:
                return _Response(err.status)
            session = RtspSession(
                self.cam,
                media,
                self.listener.parameter_sets(media),
                self.listener.session_timeout_s,
                self.send,
                lambda: self.end(),
            )
            self.sessions[session.id] = session
        session.channels = channels
        ssrc = session.packetizer.ssrc
        tp = f'RTP/AVP/TCP;unicast;interleaved={channels[0]}-{channels[1]};ssrc={ssrc:08X};mode="PLAY"'
        timeout = max(1, round(session.timeout_s))
        return _Response(200, [("Transport", tp), ("Session", f"{session.id};timeout={timeout}")])

    def _play(self, req: _Request, url: urllib.parse.SplitResult, sid: str) -> _Response:
        session = self._session(sid)
        if session.playing:
            return _Response(200, [("Session", sid), ("Range", "npt=now-")])
        seq, rtptime = session.prepare_play()
        stream = f"rtsp://{url.netloc}{MEDIA_PATH}/stream=0"
        info = f"url={stream};seq={seq};rtptime={rtptime}"
        return _Response(200, [("Session", sid), ("Range", "npt=now-"), ("RTP-Info", info)])

    def _teardown(self, req: _Request, url: urllib.parse.SplitResult, sid: str) -> _Response:
        self._session(sid).stop()
        self.listener.drop(sid)
        return _Response(200)

    def _get_parameter(self, req: _Request, url: urllib.parse.SplitResult, sid: str) -> _Response:
        return _Response(200, [("Session", sid)])

    def _set_parameter(self, req: _Request, url: urllib.parse.SplitResult, sid: str) -> _Response:
        session = self._session(sid)
        renew = False
        adjust: tuple[int | None, int | None] | None = None
        for line in req.body.decode("utf-8", "replace").splitlines():
            if not line.strip():
                continue
            k, _, v = line.partition(":")
            k, v = k.strip().lower(), v.strip()
            if k == "renew-stream" and v.lower() == "yes":
                renew = True
            elif k == "adjustable-stream-configuration" and session.request.adjustable:
                adjust = _adjustment(v)
                if adjust is None:
                    return _Response(400, [("Session", sid)])
            else:
                return _Response(451, [("Session", sid)])
        if adjust is not None:
            session.adjust(*adjust)
        if renew:
            session.renew()
        return _Response(200, [("Session", sid)])


def _adjustment(value: str) -> tuple[int | None, int | None] | None:
    """``fps=…,videomaxbitrate=…`` → (fps, kbit/s); None if a value is bad."""
    fps: int | None = None
    kbps: int | None = None
    for item in value.split(","):
        k, _, v = item.strip().partition("=")
        if not v.isdigit():
            return None
        if k == "fps" and 1 <= int(v) <= MAX_FPS:
            fps = int(v)
        elif k == "videomaxbitrate" and 50 <= int(v) <= 50_000:
            kbps = int(v)
        else:
            return None
    return fps, kbps
