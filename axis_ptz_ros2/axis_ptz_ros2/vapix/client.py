"""Synchronous, typed VAPIX client for Axis PTZ cameras (ROS-free).

Implements reference ``vapix.md``: §2 (base URL, v2/v3 param.cgi paths, line endings), §3
(authentication via :class:`~axis_ptz_ros2.vapix.auth.NegotiatingAuth`), §4 (``ptz.cgi`` commands
and queries, ``ptzconfig.cgi`` presets, ``Error:`` bodies), §5 (``mjpg/video.cgi`` stream,
``jpg/image.cgi`` snapshot, ``imagesize.cgi`` for CIF names), §6 (``param.cgi?action=list``) and
the robustness checklist of §12.

Threading: one PTZ caller (serialised by a lock) plus any number of :class:`MjpegStream` objects,
each on its own ``httpx.Client`` (all sharing one SSL context), so a long-lived video stream never blocks PTZ
polling.
Credentials live only in :class:`CameraConfig` (``repr=False``) and the auth objects; URLs and
error messages never contain them.
"""

from __future__ import annotations

import contextlib
import os
import re
import socket
import ssl
import threading
import time
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from types import TracebackType
from typing import Self
from urllib.parse import quote

import httpx

from axis_ptz_ros2 import __version__
from axis_ptz_ros2.vapix.auth import AuthCounters, AuthMode, NegotiatingAuth, read_challenge_body
from axis_ptz_ros2.vapix.errors import (
    AuthError,
    AxisPtzError,
    CameraTimeout,
    CommandRejected,
    HttpStatusError,
    InvalidArgument,
    ResponseParseError,
    check_status,
    describe_request,
    map_httpx_error,
    redact,
)
from axis_ptz_ros2.vapix.keepalive import KeepAliveTransport
from axis_ptz_ros2.vapix.mjpeg import MjpegParser, MjpegStats, boundary_from_content_type
from axis_ptz_ros2.vapix.models import (
    CIF_NTSC,
    CIF_PAL,
    DeviceInfo,
    Preset,
    PtzLimits,
    PtzPosition,
    Resolution,
    VideoParams,
    parse_bool,
    parse_int,
    parse_key_values,
)
from axis_ptz_ros2.vapix.requests import PTZ_CGI, PtzQuery, PtzRequest

__all__ = ["USER_AGENT", "CameraConfig", "MjpegStream", "VapixClient", "build_path", "parse_error_body"]

USER_AGENT = f"axis_ptz_ros2/{__version__}"
PARAM_CGI_PATHS = ("/axis-cgi/param.cgi", "/axis-cgi/view/param.cgi")
IMAGESIZE_CGI_PATHS = ("/axis-cgi/imagesize.cgi", "/axis-cgi/view/imagesize.cgi")
VIDEO_CGI = "/axis-cgi/mjpg/video.cgi"
MAX_REPLY_BYTES = 1 << 20  #: cap on a text reply (param listings of real cameras are < 200 kB)
MAX_SNAPSHOT_BYTES = 32 << 20  #: cap on one snapshot JPEG
MAX_ERROR_BODY_BYTES = 64 << 10  #: what we read of a non-2xx reply (the rest is dropped)
IMAGE_CGI = "/axis-cgi/jpg/image.cgi"
_NTSC_HEIGHTS = frozenset({480, 240, 120})
_PAL_HEIGHTS = frozenset({576, 288, 144})
MAX_CACHED_URLS = 64  #: parsed URLs kept for repeated requests (cleared when full)
_HTML_ERROR = re.compile(r"(?is)Error:\s*(.*?)\s*</body>")
_XML_ENTRY = re.compile(r"<entry\b([^>]*)>")
_XML_ATTR = re.compile(r'(\w+)="([^"]*)"')
_NICE_SIZE = re.compile(r"\((\d+)\s*[xX]\s*(\d+)\)")


def build_path(path: str, args: Mapping[str, str]) -> str:
    """``path?k=v&…`` with RFC 3986 percent-encoding (spaces as ``%20``; ``,`` kept, §2.1)."""
    if not args:
        return path
    query = "&".join(f"{quote(k, safe='')}={quote(v, safe=',-._~')}" for k, v in args.items())
    return f"{path}?{query}"


def parse_error_body(text: str) -> str | None:
    """The camera message of an ``Error:`` body (same-line, next-line or old HTML form), else None."""
    stripped = text.strip()
    if stripped.startswith("Error"):
        first, _, rest = stripped.partition("\n")
        message = first[len("Error") :].lstrip(":").strip()
        if not message:
            message = next((line.strip() for line in rest.splitlines() if line.strip()), "")
        return message or "(no message)"
    match = _HTML_ERROR.search(text)
    if match and stripped[:1] == "<":
        return re.sub(r"<[^>]+>", "", match.group(1)).strip() or "(no message)"
    return None


def _decode(body: bytes) -> str:
    try:
        return body.decode("utf-8")
    except UnicodeDecodeError:
        return body.decode("latin-1")


def _attach_request(err: httpx.HTTPError, request: httpx.Request) -> None:
    """Give a transport error its request (as ``httpx.Client`` does), so messages can name it."""
    try:
        err.request  # noqa: B018 - raises when unset
    except RuntimeError:
        err.request = request


@dataclass(frozen=True, slots=True)
class CameraConfig:
    """Where and how to reach the camera. ``password`` is never shown in ``repr``."""

    host: str = "127.0.0.1"
    port: int | None = None
    use_https: bool = False
    verify_tls: bool | str = True
    username: str | None = None
    password: str | None = field(default=None, repr=False)
    camera: int = 1
    timeout_s: float = 5.0
    connect_timeout_s: float = 2.0
    auth: str = "auto"

    def __post_init__(self) -> None:
        """Refuse configurations that cannot work (the request would never be sent)."""
        if not self.host or any(c in self.host for c in "/@?# "):
            raise InvalidArgument(f"host must be a bare host name or address, got {self.host!r}")
        if self.port is not None and not 0 < self.port < 65536:
            raise InvalidArgument(f"port must be 1..65535, got {self.port}")
        if self.camera < 1:
            raise InvalidArgument(f"camera must be >= 1, got {self.camera}")
        if self.timeout_s <= 0 or self.connect_timeout_s <= 0:
            raise InvalidArgument("timeouts must be positive")
        try:
            AuthMode(self.auth)
        except ValueError as err:
            modes = ", ".join(m.value for m in AuthMode)
            raise InvalidArgument(f"auth must be one of {modes}, got {self.auth!r}") from err
        if (self.username is None) != (self.password is None):
            raise InvalidArgument("username and password must be given together")

    @property
    def base_url(self) -> str:
        """``http://host[:port]`` without credentials (IPv6 literals bracketed)."""
        scheme = "https" if self.use_https else "http"
        host = f"[{self.host}]" if ":" in self.host and not self.host.startswith("[") else self.host
        return f"{scheme}://{host}" + (f":{self.port}" if self.port is not None else "")

    @property
    def tcp_port(self) -> int:
        """The TCP port the requests go to: ``port``, else the scheme's default (443 for HTTPS, else 80)."""
        if self.port is not None:
            return self.port
        return 443 if self.use_https else 80

    def ssl_verify(self) -> ssl.SSLContext | bool:
        """``verify_tls`` for httpx: a bool, or a CA file/directory turned into an SSL context."""
        if isinstance(self.verify_tls, bool):
            return self.verify_tls
        try:
            if os.path.isdir(self.verify_tls):
                return ssl.create_default_context(capath=self.verify_tls)
            return ssl.create_default_context(cafile=self.verify_tls)
        except (OSError, ssl.SSLError) as err:
            raise InvalidArgument(f"verify_tls: cannot load CA bundle {self.verify_tls!r} ({err})") from err

    def timeout(self, read_timeout_s: float | None = None) -> httpx.Timeout:
        """httpx timeout: connect from ``connect_timeout_s``, the rest from ``timeout_s``."""
        read = self.timeout_s if read_timeout_s is None else read_timeout_s
        return httpx.Timeout(self.timeout_s, connect=self.connect_timeout_s, read=read)


class _ClosesOnExit:
    """A context manager that calls ``close()`` on exit (the client, a stream)."""

    def close(self) -> None:
        """Release what is held (each class its own)."""
        raise NotImplementedError

    def __enter__(self) -> Self:
        """Context manager: closes on exit."""
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        """Close."""
        self.close()


class VapixClient(_ClosesOnExit):
    """Typed access to one Axis camera over one kept-alive ``httpx.Client``."""

    def __init__(
        self,
        config: CameraConfig,
        *,
        transport: httpx.BaseTransport | None = None,
        auth_counters: AuthCounters | None = None,
    ) -> None:
        """``transport`` is injected by tests (``httpx.MockTransport``); default: a real HTTP transport.
        ``auth_counters`` may be shared by several clients of one camera (diagnostics add them up once)."""
        self._config = config
        self._transport = transport
        #: re-challenges, refusals (this client and its streams)
        self.auth_counters = auth_counters if auth_counters is not None else AuthCounters()
        self._auth = NegotiatingAuth(config.username, config.password, config.auth, counters=self.auth_counters)
        self._verify = config.ssl_verify() if config.use_https else True
        # One connection pool for every PTZ request: the httpx.Client (kept for callers that want one) and the
        # direct path of :meth:`_exchange` share it, so there is still one kept-alive connection.
        self._pool: httpx.BaseTransport = (
            transport if transport is not None else httpx.HTTPTransport(verify=self._verify, trust_env=False)
        )
        self._http = self._new_http(self._auth, config.timeout(), self._pool)
        # the parts of a request that never change, built once (the position poll sends 20 requests a second)
        self._headers = httpx.Headers(self._http.headers)
        self._extensions: dict[str, object] = {"timeout": self._http.timeout.as_dict()}
        self._urls: dict[str, httpx.URL] = {}
        self._timeouts: dict[str, float | None] = self._http.timeout.as_dict()
        self._timeout_s = config.timeout_s
        # queries over our own transport take its quick path while replies are plain (keepalive.py says why)
        self._quick = self._pool if isinstance(self._pool, KeepAliveTransport) else None
        self._quick_requests: dict[str, tuple[httpx.Request, bytes]] = {}
        self.quick_declined = ""  #: why queries stopped taking the quick path (empty: they take it, or no quick path)
        self.quick_replies = 0  #: queries answered over the quick path
        self._lock = threading.RLock()
        self._stream_ssl: ssl.SSLContext | None = None  # every MJPEG stream's, built once (_stream_ssl_context)
        self._stream_ssl_lock = threading.Lock()
        self._param_path: str | None = None
        self._imagesize_path: str | None = None
        self._limits: PtzLimits | None = None
        self._resolutions: tuple[Resolution, ...] | None = None
        self._ntsc: bool | None = None
        self._asked_standard = False
        self.resolution_problem = ""  #: why some listed resolution names have no size (empty: none)

    def _new_http(
        self,
        auth: httpx.Auth,
        timeout: httpx.Timeout,
        transport: httpx.BaseTransport | None,
        verify: ssl.SSLContext | bool | None = None,
    ) -> httpx.Client:
        return httpx.Client(
            base_url=self._config.base_url,
            auth=auth,
            timeout=timeout,
            verify=self._verify if verify is None else verify,
            transport=transport,
            headers={"User-Agent": USER_AGENT},
            follow_redirects=False,
            trust_env=False,
        )

    # -- lifecycle ------------------------------------------------------------------------------

    @property
    def config(self) -> CameraConfig:
        """The configuration this client was built with."""
        return self._config

    @property
    def limits(self) -> PtzLimits | None:
        """Limits from the last :meth:`query_limits` (used to validate every command)."""
        return self._limits

    def close(self) -> None:
        """Close the PTZ connection (streams are closed by their own ``close``)."""
        self._http.close()

    def __repr__(self) -> str:
        """No credentials."""
        return f"VapixClient({self._config!r})"

    # -- transport ------------------------------------------------------------------------------

    def _secrets(self) -> tuple[str | None, ...]:
        return (self._config.password,)

    def _url(self, path_query: str) -> httpx.URL:
        """The absolute URL of ``path_query``, parsed once for requests that repeat (the position poll)."""
        url = self._urls.get(path_query)
        if url is None:
            url = httpx.URL(self._config.base_url + path_query)
            if len(self._urls) >= MAX_CACHED_URLS:  # commands carry their values: bounded, not an LRU
                self._urls.clear()
            self._urls[path_query] = url
        return url

    def _send_one(self, request: httpx.Request) -> httpx.Response:
        try:
            response = self._pool.handle_request(request)
        except httpx.HTTPError as err:
            _attach_request(err, request)
            raise
        response.request = request
        return response

    def _exchange(self, path_query: str) -> httpx.Response:
        """GET ``path_query`` through the authentication flow; returns the final response, body unread.

        What ``httpx.Client.send`` does for us, without what we do not use: no cookie jar (VAPIX does not use
        cookies; the jar's per-response bookkeeping was ~10 % of a poll), no URL merging per request, no
        redirects (``follow_redirects=False`` before too). Timeouts go in the request extensions as the client
        put them. A 401 answered with another request is read capped (:func:`read_challenge_body`) and closed.
        """
        request = httpx.Request("GET", self._url(path_query), headers=self._headers, extensions=self._extensions)
        flow = self._auth.sync_auth_flow(request)
        try:
            request = next(flow)
            while True:
                response = self._send_one(request)
                try:
                    request = flow.send(response)
                except StopIteration:
                    return response
                except BaseException:
                    response.close()
                    raise
                try:
                    read_challenge_body(response)
                finally:
                    response.close()
        finally:
            flow.close()

    def _get(
        self, path_query: str, max_bytes: int = MAX_REPLY_BYTES, total_s: float | None = None
    ) -> tuple[httpx.Response, bytes]:
        """GET, map transport errors and non-2xx statuses; returns a 2xx response (closed) and its body.

        The body is read with a size cap and a total-time cap (``total_s``, default ``timeout_s``): a port
        that serves a video stream or an endless page gives a clear :class:`ResponseParseError`, never memory
        growth or a thread blocked for ever.
        """
        with self._lock:
            try:
                response = self._exchange(path_query)
                try:
                    ok = 200 <= response.status_code < 300
                    cap = max_bytes if ok else MAX_ERROR_BODY_BYTES
                    body = self._read_capped(response, cap, strict=ok, total_s=total_s)
                finally:
                    response.close()
            except httpx.HTTPError as err:
                raise map_httpx_error(err, self._secrets()) from err
        if not 200 <= response.status_code < 300:
            self._check(response)
        return response, body

    def _read_capped(
        self, response: httpx.Response, max_bytes: int, *, strict: bool, total_s: float | None = None
    ) -> bytes:
        where = response.request  # named in an error only (describe_request is not free, the poll's reply is)
        ctype = response.headers.get("content-type", "")
        if strict and ctype.lower().startswith("multipart/"):
            raise ResponseParseError(
                f"{describe_request(where)}: the camera answers with a stream ({ctype!r}), not a reply: is this "
                "the camera's VAPIX port, or a video/stream port?"
            )
        total = self._config.timeout_s if total_s is None else total_s
        deadline = time.monotonic() + total
        chunks: list[bytes] = []
        size = 0
        # without a Content-Encoding the raw bytes are the body (skips httpx's identity decoder per chunk); a
        # response built with its content (a test's MockTransport) is already read: iter_bytes yields it
        raw = not response.is_stream_consumed and "content-encoding" not in response.headers
        for chunk in response.iter_raw() if raw else response.iter_bytes():
            size += len(chunk)
            if size > max_bytes:
                if not strict:
                    chunks.append(chunk[: max(0, len(chunk) - (size - max_bytes))])
                    break
                raise ResponseParseError(
                    f"{describe_request(where)}: reply larger than {max_bytes} bytes "
                    f"({ctype or 'no content type'}): not a VAPIX reply (a stream or a huge page; check the port)"
                )
            chunks.append(chunk)
            if time.monotonic() > deadline:
                if not strict:
                    break
                raise CameraTimeout(
                    f"{describe_request(where)}: reply still arriving after {total:g} s ({size} bytes): not a "
                    "VAPIX reply (a stream or a trickling page; check the port)"
                )
        return b"".join(chunks)

    def _check(self, response: httpx.Response) -> None:
        hint = self._auth.failure_hint(response) if response.status_code in (401, 403) else ""
        check_status(response, auth_hint=redact(hint, self._secrets()))

    def _get_text(self, path_query: str) -> tuple[httpx.Response, str]:
        response, body = self._get(path_query)
        text = _decode(body)
        message = parse_error_body(text)
        if message is not None:
            raise CommandRejected(
                f"{describe_request(response.request)}: camera says {message!r}", camera_message=message
            )
        return response, text

    def _camera_args(self) -> dict[str, str]:
        return {"camera": str(self._config.camera)} if self._config.camera != 1 else {}

    # -- PTZ ------------------------------------------------------------------------------------

    def ptz(self, cmd: PtzRequest) -> None:
        """Validate ``cmd`` (against :attr:`limits` when known) and send it; expects 204/2xx.

        Raises :class:`InvalidArgument` before sending, :class:`CommandRejected` on an ``Error:``
        body, or the mapped transport/status error.
        """
        cmd.validate(self._limits)
        self._get_text(build_path(cmd.path, {**self._camera_args(), **cmd.query()}))

    def _query(self, what: PtzQuery) -> str:
        path_query = build_path(PTZ_CGI, {**self._camera_args(), "query": what.value})
        if self._quick is not None:
            text = self._quick_text(path_query)
            if text is not None:
                return text
        _, text = self._get_text(path_query)
        return text

    def _quick_request(self, path_query: str) -> tuple[httpx.Request, bytes]:
        """The request of ``path_query`` (for signatures and error messages) and its head as sent, without the
        ``Authorization`` line and the final empty line; built once per query. The camera is asked for the
        identity coding (a coded reply goes the full path)."""
        prepared = self._quick_requests.get(path_query)
        if prepared is None:
            request = httpx.Request("GET", self._url(path_query), headers=self._headers, extensions=self._extensions)
            lines = [b"GET " + request.url.raw_path + b" HTTP/1.1"]
            for name, value in request.headers.raw:
                if name.lower() == b"accept-encoding":
                    value = b"identity"
                lines.append(name + b": " + value)
            prepared = request, b"\r\n".join(lines) + b"\r\n"
            self._quick_requests[path_query] = prepared
        return prepared

    def _quick_text(self, path_query: str) -> str | None:
        """The text of a 2xx reply to ``path_query`` over the transport's quick path; None when the full path
        must answer (not signable ahead, a non-2xx reply, an ``Error:`` body: it asks again and raises what it
        always raised; a reply the quick path does not read: queries take the full path from then on)."""
        with self._lock:
            quick = self._quick
            if quick is None:
                return None
            request, head = self._quick_request(path_query)
            authorization = self._auth.preemptive(request)
            if authorization is None or not authorization.isascii():
                return None
            if authorization:
                head += b"Authorization: " + authorization.encode("ascii") + b"\r\n"
            try:
                reply = quick.quick_get(
                    request.url, head + b"\r\n", self._timeouts, max_bytes=MAX_REPLY_BYTES, total_s=self._timeout_s
                )
            except httpx.HTTPError as err:
                _attach_request(err, request)
                raise map_httpx_error(err, self._secrets()) from err
            if reply is None:
                self._quick = None
                self.quick_declined = f"{describe_request(request)}: a reply the quick path does not read"
                return None
            status, body = reply
            if not 200 <= status < 300:
                return None
            self._auth.accepted(signed=bool(authorization))
            text = _decode(body)
            if parse_error_body(text) is not None:
                return None
            self.quick_replies += 1
            return text

    def query_position(self) -> PtzPosition:
        """``query=position`` (§4.4)."""
        return PtzPosition.parse(self._query(PtzQuery.POSITION))

    def query_limits(self) -> PtzLimits:
        """``query=limits``, falling back to ``param.cgi`` ``PTZ.Limit.L<camera>``; cached for validation."""
        try:
            limits = PtzLimits.parse(self._query(PtzQuery.LIMITS))
        except (CommandRejected, ResponseParseError) as query_err:
            try:
                limits = PtzLimits.from_params(self.list_params("PTZ.Limit"), camera=self._config.camera)
            except AxisPtzError:
                raise query_err from None
        self._limits = limits
        return limits

    def query_presets(self) -> tuple[Preset, ...]:
        """``query=presetposcam`` → presets sorted by number."""
        return Preset.parse_list(self._query(PtzQuery.PRESETPOSCAM))

    def query_speed(self) -> int:
        """``query=speed`` → 1..100."""
        values = parse_key_values(self._query(PtzQuery.SPEED))
        if "speed" not in values:
            raise ResponseParseError(f"query=speed: no 'speed' in reply (keys: {sorted(values)})")
        return parse_int(values["speed"], key="speed")

    def query_attributes(self) -> dict[str, str]:
        """``query=attributes`` (newer firmware only, §4.4): ``maxOpticalZoomMag``, ``maxDigitalZoomMag``,
        ``zoomSteps``, ``speeds`` as raw text values. Raises :class:`CommandRejected` where unsupported."""
        return parse_key_values(self._query(PtzQuery.ATTRIBUTES))

    # -- parameters -----------------------------------------------------------------------------

    def _list_at(self, path: str, group: str) -> dict[str, str]:
        _, text = self._get_text(build_path(path, {"action": "list", "group": group}))
        errors = [line.strip().lstrip("#").strip() for line in text.splitlines() if line.lstrip().startswith("#")]
        errors = [e for e in errors if e.startswith("Error")]
        if errors:
            message = errors[0].partition(":")[2].strip() or errors[0]
            raise CommandRejected(f"{path}?action=list&group={group}: camera says {message!r}", camera_message=message)
        return parse_key_values(text)

    def list_params(self, group: str) -> dict[str, str]:
        """``param.cgi?action=list&group=<group>`` → ``{name: value}`` with ``root.`` stripped.

        Tries the v3 path ``/axis-cgi/param.cgi`` then the v2 path ``/axis-cgi/view/param.cgi``
        (the 214) and remembers which one answered. ``# Error:`` lines raise :class:`CommandRejected`.
        """
        if not group or any(c in group for c in "&=?#"):
            raise InvalidArgument(f"bad parameter group {group!r}")
        if self._param_path is not None:
            return self._list_at(self._param_path, group)
        first_error: HttpStatusError | AuthError | None = None
        for path in PARAM_CGI_PATHS:
            try:
                values = self._list_at(path, group)
            except HttpStatusError as err:
                if err.status_code != 404:
                    raise
                first_error = first_error or err
                continue
            except AuthError as err:
                # Firmware 5.0-5.6 answers the v3 path with 401 even to allowed users (vapix.md §2.2): the
                # legacy path may still answer. A 401 there too is the real answer (reported first).
                first_error = err if not isinstance(first_error, AuthError) else first_error
                continue
            self._param_path = path
            return values
        assert first_error is not None  # noqa: S101 - loop ran at least once
        raise first_error

    def _imagesize(self, name: str | None) -> Resolution | None:
        """Ask ``imagesize.cgi`` (§5.3) the size of ``name`` (None: the camera's default); None if it cannot."""
        if self._imagesize_path == "":
            return None  # neither path answered before
        args = {"squarepixel": "0", **self._camera_args()}
        if name is not None:
            args = {"resolution": name, **args}
        paths = (self._imagesize_path,) if self._imagesize_path else IMAGESIZE_CGI_PATHS
        answered = False
        for path in paths:
            assert path is not None  # noqa: S101
            try:
                _, text = self._get_text(build_path(path, args))
            except HttpStatusError:
                continue
            except CommandRejected:
                answered = True
                continue
            answered = True
            values = {k.strip().lower(): v for k, v in parse_key_values(text).items()}
            try:
                width = parse_int(values["image width"], key="image width")
                height = parse_int(values["image height"], key="image height")
            except (KeyError, ResponseParseError):
                continue
            self._imagesize_path = path
            return Resolution(width, height)
        if not answered and self._imagesize_path is None:
            self._imagesize_path = ""  # no imagesize.cgi on this camera: do not ask again for every name
        return None

    def _video_standard(self) -> bool | None:
        """NTSC (True) or PAL (False) from the camera's own default image size (``imagesize.cgi``), else from the
        video input it reports (:meth:`_reported_standard`); None if it cannot say."""
        if self._ntsc is None:
            size = self._imagesize(None)
            if size is not None and size.height in _NTSC_HEIGHTS:
                self._ntsc = True
            elif size is not None and size.height in _PAL_HEIGHTS:
                self._ntsc = False
            elif not self._asked_standard:
                self._asked_standard = True  # once: a camera without the group is not asked per name
                self._ntsc = self._reported_standard()
        return self._ntsc

    def _reported_standard(self) -> bool | None:
        """NTSC (True) / PAL (False) as the camera reports its analogue video input:
        ``ImageSource.I<n>.Video.DetectedType`` (the signal found), else ``CaptureMode`` (both recorded on an
        AXIS P5512, firmware 5.51, vapix.md S8); None if it reports neither (a camera without such a group)."""
        group = f"ImageSource.I{self._config.camera - 1}.Video"
        try:
            values = self.list_params(group)
        except (CommandRejected, HttpStatusError, AuthError, ResponseParseError):
            return None
        for key in ("DetectedType", "CaptureMode"):
            value = values.get(f"{group}.{key}", "").strip().upper()
            if value in ("PAL", "NTSC"):
                return value == "NTSC"
        return None

    def _defined_sizes(self) -> dict[str, Resolution]:
        """Sizes the resolution parameter's definition gives its names (``param.cgi?action=listdefinitions``,
        entries like ``<entry value="4CIF" niceValue="4CIF (704x480)" />`` as recorded on an AXIS P5512,
        firmware 5.51); empty if the camera gives none."""
        group = f"Image.I{self._config.camera - 1}.Appearance.Resolution"
        args = {"action": "listdefinitions", "listformat": "xmlschema", "group": group}
        try:
            _, text = self._get_text(build_path(self._param_path or PARAM_CGI_PATHS[0], args))
        except (CommandRejected, HttpStatusError, AuthError, ResponseParseError):
            return {}
        sizes: dict[str, Resolution] = {}
        for tag in _XML_ENTRY.findall(text):
            attrs = dict(_XML_ATTR.findall(tag))
            match = _NICE_SIZE.search(attrs.get("niceValue", ""))
            if "value" in attrs and match and int(match.group(1)) > 0 and int(match.group(2)) > 0:
                sizes[attrs["value"].strip().upper()] = Resolution(int(match.group(1)), int(match.group(2)))
        return sizes

    def _resolutions_from(self, listing: str) -> tuple[Resolution, ...]:
        """Sizes of the camera's resolution names. CIF/D1 names are sized by the camera itself: the first one
        through ``imagesize.cgi`` (which tells PAL from NTSC), else the video standard of the camera's default
        size or of the video input it reports; without ``imagesize.cgi`` (some firmware answers 404) and
        without a reported standard, from the parameter's definition, else the sizes of both standards
        (:meth:`_size_unsized`) — never an empty list for a non-empty listing, never silently PAL."""
        names = [n.strip() for n in listing.split(",") if n.strip()]
        result: list[Resolution] = []
        unsized: list[str] = []
        for name in names:
            upper = name.upper()
            resolution: Resolution | None
            try:
                resolution = Resolution.parse(name) if upper not in CIF_PAL else None
            except InvalidArgument:
                resolution = None
            if resolution is None and upper in CIF_PAL and self._ntsc is not None:
                resolution = Resolution(*(CIF_NTSC if self._ntsc else CIF_PAL)[upper])  # standard known
            if resolution is None:
                resolution = self._imagesize(upper if upper in CIF_PAL else name)
                if resolution is not None and upper in CIF_PAL and self._ntsc is None:
                    if resolution == Resolution(*CIF_NTSC[upper]):
                        self._ntsc = True
                    elif resolution == Resolution(*CIF_PAL[upper]):
                        self._ntsc = False
            if resolution is None and upper in CIF_PAL:
                ntsc = self._video_standard()
                if ntsc is not None:
                    resolution = Resolution(*(CIF_NTSC if ntsc else CIF_PAL)[upper])
            if resolution is None:
                unsized.append(name)
            elif resolution not in result:
                result.append(resolution)
        self.resolution_problem = ""
        if unsized:
            result += self._size_unsized(unsized, result)
        return tuple(result)

    def _size_unsized(self, unsized: list[str], known: list[Resolution]) -> list[Resolution]:
        """Sizes for names neither ``imagesize.cgi`` nor a reported video standard could size: from the
        resolution parameter's definition, else (CIF names) the sizes of both video standards, so the list is
        never empty; what was not known for sure is said in :attr:`resolution_problem`."""
        defined = self._defined_sizes()
        out: list[Resolution] = []
        guessed: list[str] = []
        for name in unsized:
            upper = name.upper()
            candidates = [defined[upper]] if upper in defined else []
            if not candidates and upper in CIF_PAL:
                candidates = [Resolution(*CIF_PAL[upper]), Resolution(*CIF_NTSC[upper])]
                guessed.append(name)
            out += [r for r in candidates if r not in known and r not in out]
        lost = [n for n in unsized if n.upper() not in defined and n.upper() not in CIF_PAL]
        problems = []
        if guessed:
            problems.append(
                f"camera lists {', '.join(guessed)} but tells neither their size (no imagesize.cgi, no parameter "
                "definition) nor PAL/NTSC: offering the sizes of both standards; configure resolution as "
                "WIDTHxHEIGHT of your camera's standard"
            )
        if lost:
            problems.append(f"camera lists {', '.join(lost)} but could not tell their size; left out")
        self.resolution_problem = "; ".join(problems)
        return out

    def supported_resolutions(self) -> tuple[Resolution, ...]:
        """``Properties.Image.Resolution`` as sizes (CIF names mapped, PAL/NTSC via ``imagesize.cgi``)."""
        params = self.list_params("Properties.Image.Resolution")
        listing = params.get("Properties.Image.Resolution")
        if listing is None:
            raise ResponseParseError(f"no Properties.Image.Resolution in reply (keys: {sorted(params)})")
        self._resolutions = self._resolutions_from(listing)
        return self._resolutions

    def device_info(self) -> DeviceInfo:
        """Product, firmware, API version, resolutions, PTZ presence and ``PTZ.Support`` capabilities."""
        brand = self.list_params("Brand")
        props = self.list_params("Properties")
        product = brand.get("Brand.ProdFullName") or brand.get("Brand.ProdShortName") or "unknown"
        version = props.get("Properties.API.HTTP.Version")
        listing = props.get("Properties.Image.Resolution", "")
        self._resolutions = self._resolutions_from(listing) if listing else ()
        ptz_flag = props.get("Properties.PTZ.PTZ")
        supports: frozenset[str] = frozenset()
        if ptz_flag is None or parse_bool(ptz_flag, key="Properties.PTZ.PTZ"):
            prefix = f"PTZ.Support.S{self._config.camera}."
            try:
                support = self.list_params("PTZ.Support")
            except CommandRejected:
                support = {}
            supports = frozenset(
                key[len(prefix) :]
                for key, value in support.items()
                if key.startswith(prefix) and value.strip().lower() in ("true", "yes", "on", "1")
            )
        ptz = parse_bool(ptz_flag, key="Properties.PTZ.PTZ") if ptz_flag is not None else bool(supports)
        if ptz and self.mechanical_ptz() is False:
            ptz = False  # a fixed camera with digital PTZ only
        return DeviceInfo(
            product=product,
            firmware=props.get("Properties.Firmware.Version", "unknown"),
            api_version=parse_int(version, key="Properties.API.HTTP.Version") if version else None,
            resolutions=self._resolutions,
            ptz=ptz,
            supports=supports,
        )

    def mechanical_ptz(self) -> bool | None:
        """``PTZ.ImageSource.I<n>.PTZEnabled``: False on fixed cameras (digital PTZ only), True on PTZ heads,
        None when the camera has no such parameter (e.g. the 214's firmware)."""
        key = f"PTZ.ImageSource.I{self._config.camera - 1}.PTZEnabled"
        try:
            values = self.list_params("PTZ.ImageSource")
        except (CommandRejected, HttpStatusError):
            return None
        value = values.get(key)
        return None if value is None else parse_bool(value, key=key)

    # -- video ----------------------------------------------------------------------------------

    def video_path(self, params: VideoParams) -> str:
        """Path and query of the MJPEG request, e.g. for logging (no host, no credentials)."""
        return build_path(VIDEO_CGI, params.query())

    def snapshot(self, params: VideoParams) -> bytes:
        """One JPEG from ``jpg/image.cgi`` (``fps`` is not sent)."""
        params.validate(self._resolutions)
        # a large JPEG over a slow link may take a while: the time cap only has to end an endless reply
        response, body = self._get(
            build_path(IMAGE_CGI, params.query(include_fps=False)),
            MAX_SNAPSHOT_BYTES,
            total_s=max(30.0, 4.0 * self._config.timeout_s),
        )
        if not body.startswith(b"\xff\xd8"):
            message = parse_error_body(_decode(body))
            if message is not None:
                raise CommandRejected(f"{IMAGE_CGI}: camera says {message!r}", camera_message=message)
            ctype = response.headers.get("content-type", "?")
            raise ResponseParseError(f"{IMAGE_CGI}: expected a JPEG, got {ctype} ({len(body)} bytes)")
        return body

    def open_mjpeg(self, params: VideoParams, read_timeout_s: float = 5.0) -> MjpegStream:
        """Open ``mjpg/video.cgi`` on a separate connection; iterate the result for JPEG frames."""
        params.validate(self._resolutions)
        if read_timeout_s <= 0:
            raise InvalidArgument(f"read timeout must be positive, got {read_timeout_s}")
        auth = NegotiatingAuth(
            self._config.username,
            self._config.password,
            self._config.auth,
            initial_scheme=self._auth.scheme,
            counters=self.auth_counters,
        )
        http = self._new_http(
            auth, self._config.timeout(read_timeout_s), self._transport, verify=self._stream_ssl_context()
        )
        stream = MjpegStream(http, self.video_path(params), auth, self._secrets())
        try:
            stream._open()
        except BaseException:
            stream.close()
            raise
        return stream

    def _stream_ssl_context(self) -> ssl.SSLContext:
        """The SSL context of every MJPEG stream of this client, built once (thread-safe).

        Given ``verify=True`` (or ``False``), httpx builds a new context for each client, and for ``True`` parses
        the CA bundle into OpenSSL each time: with a context per reconnect the reader thread's malloc arena grew
        ~0.2-0.35 MB per reconnect without bound, although every context was freed (issue 25).
        One context serves any number of connections; it is also what a plain-HTTP camera's client is handed
        (httpx wants one; with redirects off it is never used)."""
        with self._stream_ssl_lock:
            if self._stream_ssl is None:
                self._stream_ssl = httpx.create_ssl_context(verify=self._verify, trust_env=False)
            return self._stream_ssl


class MjpegStream(_ClosesOnExit):
    """A running MJPEG request: iterate for frames; :meth:`close` may be called from any thread."""

    def __init__(
        self, http: httpx.Client, path_query: str, auth: NegotiatingAuth, secrets: tuple[str | None, ...]
    ) -> None:
        """Use :meth:`VapixClient.open_mjpeg`."""
        self._http = http
        self._path = path_query
        self._auth = auth
        self._secrets = secrets
        self._response: httpx.Response | None = None
        self._parser: MjpegParser | None = None
        self._closed = threading.Event()
        self._lock = threading.Lock()
        self._reading = False
        self._released = False

    @property
    def path(self) -> str:
        """Path and query of the request."""
        return self._path

    @property
    def content_type(self) -> str:
        """The ``Content-Type`` the camera announced."""
        return self._response.headers.get("content-type", "") if self._response is not None else ""

    @property
    def stats(self) -> MjpegStats:
        """Parser counters so far."""
        return self._parser.stats if self._parser is not None else MjpegStats()

    @property
    def closed(self) -> bool:
        """Whether :meth:`close` was called."""
        return self._closed.is_set()

    def _open(self) -> None:
        request = self._http.build_request("GET", self._path)
        try:
            response = self._http.send(request, stream=True)
        except httpx.HTTPError as err:
            raise map_httpx_error(err, self._secrets) from err
        self._response = response
        if not 200 <= response.status_code < 300:
            with contextlib.suppress(httpx.HTTPError):
                response.read()
            hint = self._auth.failure_hint(response) if response.status_code in (401, 403) else ""
            check_status(response, auth_hint=redact(hint, self._secrets))
        ctype = response.headers.get("content-type", "")
        if not ctype.lower().startswith("multipart/"):
            text = ""
            with contextlib.suppress(httpx.HTTPError):
                text = _decode(response.read()[:4096])
            message = parse_error_body(text)
            if message is not None:
                raise CommandRejected(f"{VIDEO_CGI}: camera says {message!r}", camera_message=message)
            raise ResponseParseError(f"{VIDEO_CGI}: expected multipart/x-mixed-replace, got {ctype!r}")
        self._parser = MjpegParser(boundary_from_content_type(ctype))

    def __iter__(self) -> Iterator[bytes]:
        """Yield each complete JPEG as it arrives; ends quietly after :meth:`close` or end of stream.

        Iterate once: when the iteration ends (end of stream, ``break``, error) the stream is closed.
        """
        response, parser = self._response, self._parser
        if response is None or parser is None:
            return
        raw = response.iter_raw()
        try:
            while not self._closed.is_set():
                with self._lock:
                    if self._closed.is_set():
                        break
                    self._reading = True
                try:
                    chunk = next(raw, None)
                except httpx.HTTPError as err:
                    if self._closed.is_set():
                        break
                    raise map_httpx_error(err, self._secrets) from err
                except (OSError, ValueError):
                    if self._closed.is_set():  # socket shut down under us by close()
                        break
                    raise
                finally:
                    with self._lock:
                        self._reading = False
                if self._closed.is_set():  # closed while we were blocked: drop what arrived late
                    break
                frames = parser.close() if chunk is None else parser.feed(chunk)
                for frame in frames:
                    if self._closed.is_set():
                        break
                    yield frame
                if chunk is None:
                    break
        finally:
            self._closed.set()
            self._release()

    def close(self) -> None:
        """Stop the stream; safe from another thread (wakes a reader blocked on a stalled camera)."""
        with self._lock:
            self._closed.set()
            reading = self._reading
        if reading:
            self._shutdown_socket()  # the reader wakes up, sees the flag and releases
        else:
            self._release()

    def _shutdown_socket(self) -> None:
        response = self._response
        if response is None:
            return
        stream = response.extensions.get("network_stream")
        get_extra = getattr(stream, "get_extra_info", None)
        sock = get_extra("socket") if get_extra is not None else None
        if isinstance(sock, socket.socket):
            with contextlib.suppress(OSError):
                sock.shutdown(socket.SHUT_RDWR)

    def _release(self) -> None:
        with self._lock:
            if self._released:
                return
            self._released = True
        if self._response is not None:
            with contextlib.suppress(httpx.HTTPError, OSError):
                self._response.close()
        self._http.close()
