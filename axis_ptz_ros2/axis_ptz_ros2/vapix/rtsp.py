"""The RTSP side of a camera that streams H.264 (VAPIX RTSP API), ROS-free, for pass-through.

- :class:`MediaStreamRequest` builds the typed ``/axis-media/media.amp`` URL (VAPIX "RTSP API": ``videocodec``,
  ``resolution``, ``fps``, ``videozgopmode=fixed``, ``videokeyframeinterval``, ``h264profile=baseline``,
  ``videobitratemode=mbr`` + ``videomaxbitrate``; never ``videozprofile=storage``, which adds B-frames).
- :class:`RtspReader` plays it with FFmpeg's RTSP client through PyAV: RTP interleaved on the RTSP TCP connection,
  open and read timeouts (without them ``demux()`` hangs on a stalled camera), packets sharing a pts merged into
  one access unit, capture time from the RTCP sender reports (``start_time_realtime`` + pts), SPS/PPS from the
  SDP (``extradata``) prepended to every IDR that lacks them.
- :class:`RtspControl` sends what FFmpeg cannot: ``SET_PARAMETER`` with ``Renew-Stream: yes`` (an IDR now) and
  ``Adjustable-Stream-Configuration`` (live fps/bitrate where ``adjustablelivestream=1``), signed with the same
  Digest negotiation as the HTTP side, over the absolute URL (:class:`~axis_ptz_ros2.vapix.rtsp_auth.RtspDigestAuth`).

``SET_PARAMETER`` acts on an RTSP *session*, and the session that plays the stream is FFmpeg's, whose ``Session``
id PyAV does not expose: :class:`RtspControl` takes the id as an argument. To control the stream it plays, use
:class:`~axis_ptz_ros2.vapix.rtsp_client.RtspClient` (our own client, which owns the playing session).

Credentials: the reader needs them in the URL (FFmpeg's only way); that URL never reaches a log line, a repr or
an exception message (:func:`~axis_ptz_ros2.vapix.errors.redact`).
"""

from __future__ import annotations

import re
import socket
import time
import urllib.parse
from collections.abc import Iterator
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Final

import av
import av.error
import httpx

from axis_ptz_ros2.media import annexb
from axis_ptz_ros2.media.errors import BitstreamError
from axis_ptz_ros2.vapix.auth import AuthMode
from axis_ptz_ros2.vapix.errors import (
    AuthError,
    AxisPtzError,
    CameraTimeout,
    CameraUnreachable,
    InvalidArgument,
    ResponseParseError,
    redact,
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


# ---- access units out of FFmpeg's packets ------------------------------------------------------------------------
@dataclass(slots=True)
class AccessUnitMerger:
    """Packets that share a pts are one access unit (FFmpeg's parser can split an IDR when the server repeats
    SPS/PPS in band): hold the last one until a packet with another pts arrives."""

    _pts: int | None = None
    _parts: list[bytes] = field(default_factory=list)
    merged: int = 0  #: packets appended to an access unit already begun

    def push(self, pts: int | None, data: bytes) -> tuple[int | None, bytes] | None:
        """Add a packet; return the previous access unit (pts, Annex B) when this one starts a new one."""
        out = None
        if self._parts and pts != self._pts:
            out = (self._pts, b"".join(self._parts))
            self._parts = []
        elif self._parts:
            self.merged += 1
        self._pts = pts
        if data:
            self._parts.append(data)
        return out

    def flush(self) -> tuple[int | None, bytes] | None:
        """The held access unit, if any."""
        if not self._parts:
            return None
        out = (self._pts, b"".join(self._parts))
        self._parts = []
        return out


@dataclass(frozen=True, slots=True)
class RtspAccessUnit:
    """One access unit from the camera: Annex B (SPS/PPS in front of every IDR), its pts and capture time."""

    data: bytes
    keyframe: bool
    pts: int
    capture_ns: int | None  # camera wall clock (RTCP sender reports); None until the first report


class RtspReader:
    """Play an RTSP H.264 stream with PyAV; iterate :meth:`access_units` (raises :class:`AxisPtzError` kinds).

    ``open_timeout_s``/``read_timeout_s`` bound every blocking call; a stalled camera raises
    :class:`CameraTimeout` instead of hanging.
    """

    def __init__(
        self,
        url: str,
        *,
        open_timeout_s: float = 5.0,
        read_timeout_s: float = 3.0,
        secrets: tuple[str | None, ...] = (),
    ) -> None:
        self._url = url
        self._open_timeout_s = open_timeout_s
        self._read_timeout_s = read_timeout_s
        self._secrets = secrets
        self._container: av.container.InputContainer | None = None
        self._params: annexb.ParameterSetTracker | None = None
        self._merger = AccessUnitMerger()

    def __repr__(self) -> str:
        return f"RtspReader({redact(self._url, self._secrets)!r})"

    def open(self) -> None:
        """Connect, DESCRIBE/SETUP/PLAY (FFmpeg), and take SPS/PPS from the SDP."""
        options = {
            "rtsp_transport": "tcp",
            "timeout": str(int(self._read_timeout_s * 1e6)),  # socket I/O timeout, µs
            "fflags": "nobuffer",
            "probesize": "32768",
            "analyzeduration": "500000",
        }
        try:
            container = av.open(self._url, options=options, timeout=(self._open_timeout_s, self._read_timeout_s))
        except av.error.HTTPUnauthorizedError as err:
            raise AuthError(f"RTSP {self._where()}: credentials refused (401)") from err
        except av.error.HTTPNotFoundError as err:
            raise CameraUnreachable(f"RTSP {self._where()}: no such stream (404)") from err
        except av.error.ExitError as err:  # FFmpeg's interrupt callback: the timeout fired
            raise CameraTimeout(f"RTSP {self._where()}: no answer within {self._open_timeout_s} s") from err
        except (av.error.FFmpegError, OSError) as err:
            raise CameraUnreachable(f"RTSP {self._where()}: {redact(str(err), self._secrets_all())}") from err
        if not container.streams.video:
            container.close()
            raise ResponseParseError(f"RTSP {self._where()}: the stream has no video")
        self._container = container
        self._params = annexb.ParameterSetTracker(self._sdp_parameter_sets())

    @property
    def merged_packets(self) -> int:
        """Packets merged into an access unit that had begun (split IDRs)."""
        return self._merger.merged

    def close(self) -> None:
        if self._container is not None:
            self._container.close()
            self._container = None

    def __enter__(self) -> RtspReader:
        self.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def access_units(self) -> Iterator[RtspAccessUnit]:
        """Access units as they arrive (equal-pts packets merged); ends when the stream ends."""
        container = self._container
        if container is None or self._params is None:
            raise InvalidArgument("RtspReader.access_units() before open()")
        stream = container.streams.video[0]
        tb = stream.time_base
        merger = self._merger = AccessUnitMerger()
        try:
            for packet in container.demux(stream):
                if packet.size == 0 and packet.pts is None:
                    continue  # demux's end-of-stream marker
                done = merger.push(packet.pts, bytes(packet))
                if done is not None:
                    au = self._finish(done, tb)
                    if au is not None:
                        yield au
        except av.error.ExitError as err:
            raise CameraTimeout(f"RTSP {self._where()}: no data within {self._read_timeout_s} s") from err
        except (av.error.FFmpegError, OSError) as err:
            raise CameraUnreachable(f"RTSP {self._where()}: {redact(str(err), self._secrets_all())}") from err
        last = merger.flush()
        if last is not None:
            au = self._finish(last, tb)
            if au is not None:
                yield au

    # ---- internals ---------------------------------------------------------------------------------------------
    def _finish(self, item: tuple[int | None, bytes], time_base: Fraction | None) -> RtspAccessUnit | None:
        pts, data = item
        assert self._params is not None
        assert self._container is not None
        try:
            data = self._params.process(data)
            key = annexb.is_idr(data)
        except BitstreamError:
            return None  # corrupt or undecodable access unit: dropped (the node counts it)
        capture_ns = None
        start_us = self._container.start_time_realtime
        if start_us is not None and start_us > 0 and pts is not None and time_base is not None:
            capture_ns = int(start_us) * 1000 + int(pts * time_base * 1_000_000_000)
        return RtspAccessUnit(data, key, pts if pts is not None else -1, capture_ns)

    def _sdp_parameter_sets(self) -> annexb.ParameterSets | None:
        assert self._container is not None
        extradata = self._container.streams.video[0].codec_context.extradata
        if not extradata:
            return None
        try:
            nals = annexb.split_nal_units(bytes(extradata))
            sps = next(n for n in nals if n[0] & 0x1F == annexb.NalType.SPS)
            pps = next(n for n in nals if n[0] & 0x1F == annexb.NalType.PPS)
            return annexb.ParameterSets(sps, pps)
        except (BitstreamError, StopIteration):
            return None

    def _secrets_all(self) -> tuple[str | None, ...]:
        return (*self._secrets, self._url)

    def _where(self) -> str:
        p = urllib.parse.urlsplit(self._url)
        return f"{p.hostname}:{p.port or 554}{p.path}"


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


def check_rtsp_status(resp: RtspResponse, where: str) -> RtspResponse:
    """``resp`` if it is 2xx; else :class:`AuthError` (401/403) or :class:`RtspStatusError` naming ``where``
    (method and host, never a URL with credentials)."""
    if resp.status in (401, 403):
        raise AuthError(f"{where}: refused ({resp.status} {resp.reason})")
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
        return check_rtsp_status(resp, f"RTSP {method} {self._host}:{self._port}")

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
