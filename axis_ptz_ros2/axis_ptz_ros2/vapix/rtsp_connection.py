"""The RTSP connection under :class:`~axis_ptz_ros2.vapix.rtsp_client.RtspClient` (ROS-free): requests out, and
what comes in on the one TCP connection taken apart — replies (matched to requests by ``CSeq``), RTP/RTCP frames
interleaved with ``$`` (handed to :meth:`RtspConnection._interleaved`), requests the server sends mid-stream
(answered: ``200 OK`` for ``OPTIONS``/``GET_PARAMETER``, ``501`` otherwise), and garbage between them (skipped up to
the next thing that can start a frame or a message, at most :data:`MAX_MESSAGE` bytes of it in a row).
"""

from __future__ import annotations

import re
import select
import socket
import threading
import time
import urllib.parse
from typing import Final

from axis_ptz_ros2.vapix.errors import CameraTimeout, CameraUnreachable, ResponseParseError
from axis_ptz_ros2.vapix.rtsp import USER_AGENT, RtspResponse, parse_rtsp_response

MAX_MESSAGE: Final = 1 << 20
_REQUEST_LINE: Final = re.compile(rb"([A-Z][A-Z_]{1,31}) (\S{1,2048}) RTSP/1\.0\r\n")
_REQUEST_START: Final = re.compile(rb"[A-Z][A-Z_]{0,31}( \S*( R?T?S?P?/?1?\.?0?\r?)?)?")
_RESYNC: Final = re.compile(rb"\$|RTSP/1\.0 |[A-Z][A-Z_]{1,31} \S{1,2048} RTSP/1\.0\r\n")


class RtspConnection:
    """One RTSP/1.0 connection's messages: :meth:`_send` a request, :meth:`_pump` what arrives (the subclass takes
    the interleaved frames in :meth:`_interleaved` and the replies from :attr:`_replies` under :attr:`_cond`)."""

    def __init__(self, host: str, port: int, url: str) -> None:
        self.url = url
        self._host, self._port = host, port
        self._sock: socket.socket | None = None
        self._buf = b""
        self._cseq = 0
        self._wlock = threading.Lock()
        self._cond = threading.Condition()
        self._replies: dict[int, RtspResponse] = {}
        self._channels = (0, 1)
        self._rx_ns = 0  # host time the last chunk arrived
        self._stray = ""  # a reply nobody waits for (for the timeout message)
        self._garbage_run = 0  # garbage bytes skipped since the last good message
        self.session_id: str | None = None  #: the playing session's id (what SET_PARAMETER names)
        self.server_requests = 0  #: requests the server sent mid-stream (answered)
        self.garbage_bytes = 0  #: bytes skipped between messages

    def _interleaved(self, channel: int, packet: bytes) -> None:
        """One ``$`` frame of ``channel`` (RTP or RTCP): the subclass's."""
        raise NotImplementedError

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

    def _where(self) -> str:
        return f"{self._host}:{self._port}{urllib.parse.urlsplit(self.url).path}"
