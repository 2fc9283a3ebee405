"""The HTTP side of the VAPIX client (ROS-free): one kept-alive connection, the authentication flow, capped replies,
typed errors, and the state poll's quick path (reference ``vapix.md`` §2, §3, §12).

:class:`VapixTransport` is the base of :class:`~axis_ptz_ros2.vapix.client.VapixClient`: the PTZ caller's
requests are serialised by its lock. Credentials live only in :class:`~axis_ptz_ros2.vapix.camera_config.CameraConfig`
and the auth objects; URLs and error messages never contain them.
"""

from __future__ import annotations

import ssl
import threading
import time
from types import TracebackType
from typing import Self

import httpx

from axis_ptz_ros2 import __version__
from axis_ptz_ros2.vapix.auth import AuthCounters, NegotiatingAuth, read_challenge_body
from axis_ptz_ros2.vapix.camera_config import CameraConfig
from axis_ptz_ros2.vapix.errors import (
    CameraTimeout,
    CommandRejected,
    ResponseParseError,
    check_status,
    describe_request,
    map_httpx_error,
    redact,
)
from axis_ptz_ros2.vapix.keepalive import KeepAliveTransport
from axis_ptz_ros2.vapix.replies import decode_text, parse_error_body

__all__ = ["MAX_REPLY_BYTES", "USER_AGENT", "ClosesOnExit", "VapixTransport", "attach_request"]

USER_AGENT = f"axis_ptz_ros2/{__version__}"
MAX_REPLY_BYTES = 1 << 20  #: cap on a text reply (param listings of real cameras are < 200 kB)
MAX_ERROR_BODY_BYTES = 64 << 10  #: what we read of a non-2xx reply (the rest is dropped)
MAX_CACHED_URLS = 64  #: parsed URLs kept for repeated requests (cleared when full)


def attach_request(err: httpx.HTTPError, request: httpx.Request) -> None:
    """Give a transport error its request (as ``httpx.Client`` does), so messages can name it."""
    try:
        err.request  # noqa: B018 - raises when unset
    except RuntimeError:
        err.request = request


class ClosesOnExit:
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


class VapixTransport(ClosesOnExit):
    """Requests to one Axis camera over one kept-alive ``httpx.Client``: GET through the authentication flow, replies
    read with size and time caps, statuses and ``Error:`` bodies mapped to typed errors."""

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

    def close(self) -> None:
        """Close the PTZ connection (streams are closed by their own ``close``)."""
        self._http.close()

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
            attach_request(err, request)
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
        text = decode_text(body)
        message = parse_error_body(text)
        if message is not None:
            raise CommandRejected(
                f"{describe_request(response.request)}: camera says {message!r}", camera_message=message
            )
        return response, text

    def _camera_args(self) -> dict[str, str]:
        return {"camera": str(self._config.camera)} if self._config.camera != 1 else {}

    # -- the quick path (the state poll's queries) ----------------------------------------------

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
                attach_request(err, request)
                raise map_httpx_error(err, self._secrets()) from err
            if reply is None:
                self._quick = None
                self.quick_declined = f"{describe_request(request)}: a reply the quick path does not read"
                return None
            status, body = reply
            if not 200 <= status < 300:
                return None
            self._auth.accepted(signed=bool(authorization))
            text = decode_text(body)
            if parse_error_body(text) is not None:
                return None
            self.quick_replies += 1
            return text
