"""The RTSP side of a camera that streams H.264 (VAPIX RTSP API), ROS-free, for pass-through.

- :class:`MediaStreamRequest` builds the typed ``/axis-media/media.amp`` URL (VAPIX "RTSP API": ``videocodec``,
  ``resolution``, ``fps``, ``videozgopmode=fixed``, ``videokeyframeinterval``, ``h264profile=baseline``,
  ``videobitratemode=mbr`` + ``videomaxbitrate``; never ``videozprofile=storage``, which adds B-frames).
- :class:`RtspControl` sends what FFmpeg cannot: ``SET_PARAMETER`` with ``Renew-Stream: yes`` (an IDR now) and
  ``Adjustable-Stream-Configuration`` (live fps/bitrate where ``adjustablelivestream=1``), signed with the same
  Digest negotiation as the HTTP side, over the absolute URL (:class:`~axis_ptz_ros2.vapix.rtsp_auth.RtspDigestAuth`).

``SET_PARAMETER`` acts on an RTSP *session*: :class:`RtspControl` takes the id as an argument. The stream is
played by :class:`~axis_ptz_ros2.vapix.rtsp_client.RtspClient` (our own client, which owns the playing session).
FFmpeg's RTSP client (through PyAV) is kept as an independent oracle in the tests (``tests/support/pyav_rtsp.py``),
not in the product.
"""

from __future__ import annotations

import re
import socket
import time
import urllib.parse
from dataclasses import dataclass
from typing import Final

import httpx

from axis_ptz_ros2.media import annexb
from axis_ptz_ros2.media.errors import BitstreamError
from axis_ptz_ros2.vapix.auth import BASIC_OVER_HTTP_HINT, AuthMode
from axis_ptz_ros2.vapix.errors import (
    AuthError,
    AxisPtzError,
    CameraTimeout,
    CameraUnreachable,
    InvalidArgument,
    ResponseParseError,
)
from axis_ptz_ros2.vapix.rtsp_auth import RtspDigestAuth

MEDIA_PATH: Final = "/axis-media/media.amp"
USER_AGENT: Final = "axis_ptz_ros2/0.1.0"


# ---- the media URL ---------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class MediaStreamRequest:
    """What to ask an Axis camera's RTSP server for (checked when built)."""

    resolution: str = "704x576"
    fps: int = 30
    keyframe_interval: int = 30  # frames (videokeyframeinterval)
    max_bitrate_kbps: int = 1000  # videomaxbitrate with videobitratemode=mbr
    adjustable: bool = False  # adjustablelivestream=1: fps/bitrate changeable with SET_PARAMETER

    def __post_init__(self) -> None:
        w, _, h = self.resolution.partition("x")
        if not (w.isdigit() and h.isdigit() and 16 <= int(w) <= 8192 and 16 <= int(h) <= 8192):
            raise InvalidArgument(f"resolution must be WIDTHxHEIGHT, got {self.resolution!r}")
        if isinstance(self.fps, bool) or not isinstance(self.fps, int) or not 1 <= self.fps <= 120:
            raise InvalidArgument(f"fps must be 1…120, got {self.fps!r}")
        kf = self.keyframe_interval
        if isinstance(kf, bool) or not isinstance(kf, int) or not 1 <= kf <= 1023:
            raise InvalidArgument(f"keyframe interval must be 1…1023 frames, got {kf!r}")
        br = self.max_bitrate_kbps
        if isinstance(br, bool) or not isinstance(br, int) or not 50 <= br <= 50_000:
            raise InvalidArgument(f"max bitrate must be 50…50000 kbit/s, got {br!r}")

    def query(self) -> list[tuple[str, str]]:
        q = [
            ("videocodec", "h264"),
            ("resolution", self.resolution),
            ("fps", str(self.fps)),
            ("videozgopmode", "fixed"),
            ("videokeyframeinterval", str(self.keyframe_interval)),
            ("h264profile", "baseline"),
            ("videobitratemode", "mbr"),
            ("videomaxbitrate", str(self.max_bitrate_kbps)),
            ("audio", "0"),
        ]
        if self.adjustable:
            q.append(("adjustablelivestream", "1"))
        return q

    def url(self, host: str, port: int = 554, username: str | None = None, password: str | None = None) -> str:
        """``rtsp://[user:pass@]host:port/axis-media/media.amp?…`` (credentials only for FFmpeg; never log it)."""
        userinfo = ""
        if username is not None and password is not None:
            userinfo = f"{urllib.parse.quote(username, safe='')}:{urllib.parse.quote(password, safe='')}@"
        netloc = f"[{host}]" if ":" in host else host
        return f"rtsp://{userinfo}{netloc}:{port}{MEDIA_PATH}?{urllib.parse.urlencode(self.query())}"


# ---- RTSP control requests (SET_PARAMETER) ----------------------------------------------------------------------
class RtspStatusError(AxisPtzError):
    """A non-2xx RTSP status other than 401/403 (404 no such stream, 454 session not found, 503 busy…)."""

    def __init__(self, message: str, *, status_code: int) -> None:
        super().__init__(message)
        self.status_code = status_code


@dataclass(frozen=True, slots=True)
class RtspResponse:
    """An RTSP/1.0 reply: status, headers (lower-case names) and body."""

    status: int
    reason: str
    headers: dict[str, str]
    body: bytes


def parse_rtsp_response(raw: bytes) -> RtspResponse:
    """Parse one RTSP/1.0 reply (status line, headers, body of Content-Length bytes)."""
    head, sep, body = raw.partition(b"\r\n\r\n")
    if not sep:
        raise ResponseParseError("RTSP reply without the blank line that ends its headers")
    lines = head.decode("latin-1").split("\r\n")
    parts = lines[0].split(" ", 2)
    # a status code is three ASCII digits (RFC 2326 §7.1.1); str.isdigit() alone also accepts '²' or '٤'
    if len(parts) < 2 or not parts[0].startswith("RTSP/") or not re.fullmatch(r"[1-9][0-9]{2}", parts[1]):
        raise ResponseParseError(f"not an RTSP status line: {lines[0][:80]!r}")
    headers: dict[str, str] = {}
    for line in lines[1:]:
        name, colon, value = line.partition(":")
        if not colon:
            raise ResponseParseError(f"malformed RTSP header line {line[:80]!r}")
        key = name.strip().lower()
        headers[key] = f"{headers[key]}, {value.strip()}" if key in headers else value.strip()
    return RtspResponse(int(parts[1]), parts[2] if len(parts) > 2 else "", headers, body)


#: the HTTP side's hint (:data:`~axis_ptz_ros2.vapix.auth.BASIC_OVER_HTTP_HINT`) for RTSP, which has no TLS here
RTSP_BASIC_HINT: Final = (
    "the camera offers only Basic authentication on RTSP; auth 'auto' never sends a password in clear: "
    "set auth: basic explicitly (accepting that risk)"
)


def rtsp_auth_hint(auth: RtspDigestAuth, resp: RtspResponse, request: httpx.Request) -> str:
    """Why a final 401/403 to ``request`` (as signed by ``auth``) happened, worded like the HTTP side's hints
    (:meth:`~axis_ptz_ros2.vapix.auth.NegotiatingAuth.failure_hint`); never a secret."""
    challenge = resp.headers.get("www-authenticate")
    fake = httpx.Response(resp.status, headers=[("WWW-Authenticate", challenge)] if challenge else [], request=request)
    hint = auth.failure_hint(fake)
    return RTSP_BASIC_HINT if hint == BASIC_OVER_HTTP_HINT else hint


def check_rtsp_status(resp: RtspResponse, where: str, hint: str = "") -> RtspResponse:
    """``resp`` if it is 2xx; else :class:`AuthError` (401/403, with ``hint``: what to change) or
    :class:`RtspStatusError` naming ``where`` (method and host, never a URL with credentials)."""
    if resp.status in (401, 403):
        raise AuthError(f"{where}: refused ({resp.status} {resp.reason})" + (f": {hint}" if hint else ""))
    if not 200 <= resp.status < 300:
        raise RtspStatusError(f"{where}: {resp.status} {resp.reason}", status_code=resp.status)
    return resp


class RtspControl:
    """RTSP requests of our own on a separate TCP connection: OPTIONS and SET_PARAMETER, Digest-signed.

    ``SET_PARAMETER`` acts on a session: pass the ``Session`` id of the playing stream.
    """

    def __init__(
        self,
        host: str,
        port: int = 554,
        *,
        username: str | None = None,
        password: str | None = None,
        auth: AuthMode | str = AuthMode.AUTO,
        timeout_s: float = 3.0,
        stream: MediaStreamRequest | None = None,
    ) -> None:
        self._host, self._port, self._timeout_s = host, port, timeout_s
        self._auth = RtspDigestAuth(username, password, auth)
        self._password = password
        self._target = f"{MEDIA_PATH}?{urllib.parse.urlencode((stream or MediaStreamRequest()).query())}"
        self._cseq = 0
        self._sock: socket.socket | None = None

    def __repr__(self) -> str:
        return f"RtspControl({self._host}:{self._port}, {self._auth!r})"

    def close(self) -> None:
        if self._sock is not None:
            self._sock.close()
            self._sock = None

    def options(self) -> RtspResponse:
        return self.request("OPTIONS", extra={})

    def describe(self) -> str:
        """The stream's SDP (``DESCRIBE``; needs the viewer's rights, so it proves the credentials)."""
        return self.request("DESCRIBE", extra={"Accept": "application/sdp"}).body.decode("utf-8", "replace")

    def renew_stream(self, session: str) -> RtspResponse:
        """Ask for an IDR now (``Renew-Stream: yes``)."""
        return self.request("SET_PARAMETER", extra={"Session": session}, body=b"Renew-Stream: yes\r\n")

    def adjust_stream(
        self, session: str, *, fps: int | None = None, max_bitrate_kbps: int | None = None
    ) -> RtspResponse:
        """Change fps and/or bitrate live (``adjustablelivestream=1`` streams on firmware that has it)."""
        items = []
        if fps is not None:
            items.append(f"fps={fps}")
        if max_bitrate_kbps is not None:
            items.append(f"videomaxbitrate={max_bitrate_kbps}")
        if not items:
            raise InvalidArgument("adjust_stream needs fps or max_bitrate_kbps")
        MediaStreamRequest(fps=fps or 30, max_bitrate_kbps=max_bitrate_kbps or 1000)  # validates
        body = f"Adjustable-Stream-Configuration: {','.join(items)}\r\n".encode()
        return self.request("SET_PARAMETER", extra={"Session": session}, body=body)

    def request(self, method: str, *, extra: dict[str, str], body: bytes = b"") -> RtspResponse:
        """One request, Digest-negotiated like the HTTP side; a non-2xx final status raises."""
        http_req = httpx.Request(method, f"http://{self._host}:{self._port}{self._target}")
        self._auth.rtsp_uri = f"rtsp://{self._host}:{self._port}{self._target}"
        flow = self._auth.auth_flow(http_req)
        req = next(flow)
        while True:
            resp = self._exchange(method, req.headers.get("Authorization"), extra, body)
            try:
                req = flow.send(httpx.Response(resp.status, headers=_www_authenticate(resp), content=b"", request=req))
            except StopIteration:
                break
        hint = rtsp_auth_hint(self._auth, resp, req) if resp.status in (401, 403) else ""
        return check_rtsp_status(resp, f"RTSP {method} {self._host}:{self._port}", hint)

    def _exchange(self, method: str, authorization: str | None, extra: dict[str, str], body: bytes) -> RtspResponse:
        self._cseq += 1
        url = f"rtsp://{self._host}:{self._port}{self._target}"
        lines = [f"{method} {url} RTSP/1.0", f"CSeq: {self._cseq}", f"User-Agent: {USER_AGENT}"]
        lines += [f"{k}: {v}" for k, v in extra.items()]
        if authorization:
            lines.append(f"Authorization: {authorization}")
        if body:
            lines += ["Content-Type: text/parameters", f"Content-Length: {len(body)}"]
        raw = ("\r\n".join(lines) + "\r\n\r\n").encode("latin-1") + body
        for attempt in (0, 1):  # a kept-alive connection the server closed: reconnect once
            try:
                sock = self._connect()
                sock.sendall(raw)
                return self._read_reply(sock)
            except TimeoutError as err:
                self.close()
                raise CameraTimeout(
                    f"RTSP {method} {self._host}:{self._port}: no reply in {self._timeout_s} s"
                ) from err
            except (ConnectionError, _ClosedError) as err:
                self.close()
                if attempt:
                    raise CameraUnreachable(f"RTSP {method} {self._host}:{self._port}: {type(err).__name__}") from err
            except OSError as err:
                self.close()
                raise CameraUnreachable(f"RTSP {method} {self._host}:{self._port}: {err.strerror}") from err
        raise CameraUnreachable(f"RTSP {method} {self._host}:{self._port}: connection lost")  # pragma: no cover

    def _connect(self) -> socket.socket:
        if self._sock is None:
            self._sock = socket.create_connection((self._host, self._port), timeout=self._timeout_s)
        return self._sock

    def _read_reply(self, sock: socket.socket) -> RtspResponse:
        buf = b""
        deadline = time.monotonic() + self._timeout_s
        while b"\r\n\r\n" not in buf:
            if len(buf) > 65536:
                raise ResponseParseError("RTSP reply headers over 64 KiB")
            chunk = sock.recv(4096)
            if not chunk:
                raise _ClosedError
            buf += chunk
            if time.monotonic() > deadline:
                raise TimeoutError
        head, _, rest = buf.partition(b"\r\n\r\n")
        probe = parse_rtsp_response(head + b"\r\n\r\n")
        length_text = probe.headers.get("content-length", "0")
        if not length_text.isdigit() or int(length_text) > 1 << 20:
            raise ResponseParseError(f"RTSP Content-Length {length_text[:20]!r}")
        while len(rest) < int(length_text):
            chunk = sock.recv(4096)
            if not chunk:
                raise _ClosedError
            rest += chunk
        return RtspResponse(probe.status, probe.reason, probe.headers, rest[: int(length_text)])


class _ClosedError(Exception):
    """The server closed the control connection."""


def sprop_parameter_sets(sdp: str) -> annexb.ParameterSets | None:
    """SPS/PPS from the first ``a=fmtp:… sprop-parameter-sets=…`` of an SDP; None if it has none."""
    for line in sdp.splitlines():
        if not line.startswith("a=fmtp:"):
            continue
        for param in line.partition(" ")[2].split(";"):
            name, _, value = param.strip().partition("=")
            if name.lower() == "sprop-parameter-sets" and value:
                try:
                    return annexb.parse_sprop_parameter_sets(value)
                except BitstreamError as err:
                    raise ResponseParseError(f"SDP sprop-parameter-sets: {err}") from err
    return None


def _www_authenticate(resp: RtspResponse) -> list[tuple[str, str]]:
    value = resp.headers.get("www-authenticate")
    return [("WWW-Authenticate", value)] if value else []
