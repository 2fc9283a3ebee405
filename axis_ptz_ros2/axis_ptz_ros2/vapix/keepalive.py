"""A small ``httpx`` transport over the standard library's ``http.client``, for the PTZ state poll (ROS-free).

Why our own: the state poll sends ``query=position`` 20 times a second on one kept-alive connection. Measured on
the 2-core development machine against the simulated camera (thread CPU per request): httpx's default transport
(httpcore + h11) ~0.27 ms, a plain ``http.client`` keep-alive request ~0.08 ms. Everything above the transport
stays httpx's and ours: the request and response objects, :class:`~axis_ptz_ros2.vapix.auth.NegotiatingAuth`
(Digest/Basic negotiation, re-challenge on stale nonces), the capped reads and the error mapping of
:mod:`~axis_ptz_ros2.vapix.errors` (this transport raises the same ``httpx`` exceptions httpcore would).

What it keeps of httpcore's behaviour that the poll relies on:

* connect / read / write timeouts from the request's ``timeout`` extension (a black-holed camera ends in
  ``ConnectTimeout`` / ``ReadTimeout``, never a blocked thread);
* an idle connection the camera closed (reboot, idle timeout) is noticed before reuse and replaced;
* a response not read to its end (a capped read) closes its connection instead of reusing it;
* the request target is sent byte for byte as ``request.url.raw_path`` (Digest signs it as sent);
* HTTPS with the same SSL context rules as httpx (``verify`` bool, CA bundle or context).

Not supported (not needed by VAPIX requests): request bodies other than empty, HTTP/2, proxies.

The quick path (:meth:`KeepAliveTransport.quick_get`, taken by :class:`~axis_ptz_ros2.vapix.client.VapixClient`'s
queries over this transport): the request head is written and the reply read straight off the kept-alive
connection's socket, without ``http.client``'s reply parsing (the ``email`` package) and without ``httpx``'s request,
response and auth-flow objects. Why: thread CPU per ``query=position`` polled at 20 Hz from the simulated camera
(median, no auth / Digest; ``bench/bench_ptz_poll.py``): 0.80 / 1.00 ms through ``httpx`` over ``http.client``,
0.46 ms for a bare ``http.client`` request (no auth; its reply parsing is the ``email`` package), 0.33 / 0.49 ms
here; the idle PTZ node went from 3.7 to 1.5 % of a core.
It reads only the plain case: ``Content-Length`` framing, no content coding, not ``multipart/*``. The client sends
what the auth flow would send first (:meth:`~axis_ptz_ros2.vapix.auth.NegotiatingAuth.preemptive`) and takes
anything but a plain 2xx reply (a 401 to re-challenge, an error status, an ``Error:`` body) through the full path
above, which asks again (the queries are idempotent GETs) and keeps every rule of it; a reply the quick path does not
read (chunked, coded, a stream) sends every later query the full path.
"""

from __future__ import annotations

import http.client
import select
import socket
import ssl
import threading
import time
from collections.abc import Iterator, Mapping
from dataclasses import dataclass

import httpx

__all__ = ["KeepAliveTransport"]

READ_CHUNK = 64 << 10  #: bytes asked of the socket per read of a body


class _Connection:
    """One ``http.client`` connection and whether it can take another request."""

    def __init__(self, conn: http.client.HTTPConnection) -> None:
        self.conn = conn
        self.connected = False

    def stale(self) -> bool:
        """An idle connection with something to read (EOF from a closed peer, or junk) cannot be reused."""
        sock = self.conn.sock
        if sock is None:
            return True
        try:
            readable, _, _ = select.select([sock], [], [], 0)
        except (OSError, ValueError):
            return True
        return bool(readable)


class _BodyStream(httpx.SyncByteStream):
    """The body of one response; closing it before the end closes the connection (it cannot be reused)."""

    def __init__(self, transport: KeepAliveTransport, connection: _Connection, response: http.client.HTTPResponse):
        self._transport = transport
        self._connection = connection
        self._response = response
        self._done = False

    def __iter__(self) -> Iterator[bytes]:
        """Chunks as they arrive (``http.client`` undoes chunked transfer coding)."""
        response = self._response
        while True:
            try:
                chunk = response.read1(READ_CHUNK)
            except TimeoutError as err:
                self._drop()
                raise httpx.ReadTimeout(str(err) or "read timed out") from err
            except (http.client.HTTPException, OSError) as err:
                self._drop()
                raise _read_error(err) from err
            if not chunk:
                if not response.isclosed():
                    response.read()  # at the end of a Content-Length body: lets http.client mark it done
                break
            yield chunk

    def _drop(self) -> None:
        if not self._done:
            self._done = True
            self._connection.conn.close()

    def close(self) -> None:
        """Give the connection back when the body was read to its end, else close it."""
        if self._done:
            return
        self._done = True
        if self._response.isclosed() and not self._response.will_close:
            self._transport._release(self._connection)
        else:
            self._response.close()
            self._connection.conn.close()


def _read_error(err: BaseException) -> httpx.TransportError:
    if isinstance(err, http.client.HTTPException):
        return httpx.RemoteProtocolError(f"{type(err).__name__}: {err}")
    return httpx.ReadError(f"{type(err).__name__}: {err}")


def _connect(connection: _Connection) -> None:
    """Open the connection if it is not open yet (its timeout is the request's connect timeout)."""
    if connection.connected:
        return
    try:
        connection.conn.connect()
    except TimeoutError as err:
        raise httpx.ConnectTimeout(str(err) or "connect timed out") from err
    except OSError as err:  # refused, unreachable, TLS handshake (ssl.SSLError is an OSError)
        raise httpx.ConnectError(f"{type(err).__name__}: {err}") from err
    connection.connected = True


MAX_HEAD_BYTES = 64 << 10  #: a reply head longer than this is refused (RemoteProtocolError), as h11 does
MAX_SKIP_BYTES = 64 << 10  #: the body of a non-2xx reply read to keep its connection (longer: connection closed)


@dataclass(frozen=True, slots=True)
class _Reply:
    status: int
    body: bytes
    reusable: bool  # the connection ends exactly after this reply and the camera keeps it open


def _recv(sock: socket.socket, deadline: float) -> bytes:
    if time.monotonic() > deadline:
        raise httpx.ReadTimeout("reply still arriving at the end of its time")
    try:
        return sock.recv(READ_CHUNK)
    except TimeoutError as err:
        raise httpx.ReadTimeout(str(err) or "read timed out") from err
    except OSError as err:
        raise httpx.ReadError(f"{type(err).__name__}: {err}") from err


_VERSIONS = (b"HTTP/1.1", b"HTTP/1.0")


def _not_plain(name: bytes, value: bytes) -> bool:
    """A header (lower-case name and value) that makes a reply one the quick path leaves to ``http.client``."""
    if name == b"transfer-encoding":
        return True
    if name == b"content-encoding":
        return value != b"identity"
    return name == b"content-type" and value.startswith(b"multipart/")


def _read_reply(sock: socket.socket, max_bytes: int, deadline: float) -> _Reply | None:
    """One HTTP/1.x reply framed by ``Content-Length`` (see :meth:`KeepAliveTransport.quick_get`); None for any
    other framing or coding, or a 2xx body over ``max_bytes`` (the connection must then be closed)."""
    data = _recv(sock, deadline)
    end = data.find(b"\r\n\r\n")
    while end < 0:
        if len(data) > MAX_HEAD_BYTES:
            raise httpx.RemoteProtocolError(f"reply head longer than {MAX_HEAD_BYTES} bytes")
        chunk = _recv(sock, deadline)
        if not chunk:
            raise httpx.RemoteProtocolError("the camera closed the connection without a complete reply head")
        data += chunk
        end = data.find(b"\r\n\r\n", max(0, len(data) - len(chunk) - 3))
    status_line, *lines = data[:end].split(b"\r\n")
    version, _, rest = status_line.partition(b" ")
    code = rest[:3]
    if version not in _VERSIONS or len(code) != 3 or not code.isdigit() or rest[3:4] not in (b"", b" "):
        raise httpx.RemoteProtocolError(f"not an HTTP/1.x status line: {status_line[:80]!r}")
    status = int(code)
    length: int | None = None
    keep = version == b"HTTP/1.1"
    for line in lines:
        name, sep, value = line.partition(b":")
        if not sep:
            raise httpx.RemoteProtocolError(f"malformed reply header line: {line[:80]!r}")
        name = name.strip().lower()
        value = value.strip().lower()
        if name == b"content-length":
            if not value.isdigit() or (length is not None and int(value) != length):
                return None
            length = int(value)
        elif name == b"connection":
            tokens = {t.strip() for t in value.split(b",")}
            keep = b"close" not in tokens and (keep or b"keep-alive" in tokens)
        elif _not_plain(name, value):
            return None
    if length is None or status < 200 or status in (204, 304):
        return None
    ok = 200 <= status < 300
    if length > (max_bytes if ok else MAX_SKIP_BYTES):
        if ok:
            return None
        return _Reply(status, b"", reusable=False)
    start = end + 4
    while len(data) < start + length:
        chunk = _recv(sock, deadline)
        if not chunk:
            raise httpx.ReadError("the camera closed the connection in the middle of a reply")
        data += chunk
    return _Reply(status, data[start : start + length], reusable=keep and len(data) == start + length)


class KeepAliveTransport(httpx.BaseTransport):
    """``http.client`` keep-alive connections to one camera behind the ``httpx`` transport API (see module)."""

    def __init__(self, verify: ssl.SSLContext | bool = True, *, max_idle: int = 1) -> None:
        """``verify`` as for ``httpx``; ``max_idle`` idle connections are kept (one caller: one)."""
        self._verify = verify
        self._ssl: ssl.SSLContext | None = None
        self._max_idle = max_idle
        self._idle: list[_Connection] = []
        self._lock = threading.Lock()
        self._closed = False

    def _ssl_context(self) -> ssl.SSLContext:
        if self._ssl is None:
            self._ssl = httpx.create_ssl_context(verify=self._verify, trust_env=False)
        return self._ssl

    def _new(self, url: httpx.URL, timeout: Mapping[str, float | None]) -> _Connection:
        host, port = url.host, url.port
        connect = timeout.get("connect")
        if url.scheme == "https":
            conn: http.client.HTTPConnection = http.client.HTTPSConnection(
                host, port or 443, timeout=connect, context=self._ssl_context()
            )
        elif url.scheme == "http":
            conn = http.client.HTTPConnection(host, port or 80, timeout=connect)
        else:
            raise httpx.UnsupportedProtocol(f"Request URL has an unsupported protocol '{url.scheme}://'.")
        return _Connection(conn)

    def _take(self, url: httpx.URL, timeout: Mapping[str, float | None]) -> _Connection:
        with self._lock:
            if self._closed:
                raise RuntimeError("transport closed")
            while self._idle:
                connection = self._idle.pop()
                if not connection.stale():
                    return connection
                connection.conn.close()
        return self._new(url, timeout)

    def _release(self, connection: _Connection) -> None:
        with self._lock:
            if not self._closed and len(self._idle) < self._max_idle:
                self._idle.append(connection)
                return
        connection.conn.close()

    def handle_request(self, request: httpx.Request) -> httpx.Response:
        """Send ``request`` on a kept-alive connection; the body is streamed (see :class:`_BodyStream`)."""
        stream = request.stream
        if not isinstance(stream, httpx.SyncByteStream):
            raise RuntimeError("KeepAliveTransport is synchronous")
        body = b"".join(stream) if request.method not in ("GET", "HEAD") else b""
        timeout = request.extensions.get("timeout", {})
        connection = self._take(request.url, timeout)
        conn = connection.conn
        try:
            _connect(connection)
            assert conn.sock is not None  # noqa: S101 - connected above
            conn.sock.settimeout(timeout.get("write"))
            try:
                conn.putrequest(request.method, request.url.raw_path.decode("ascii"), skip_host=True,
                                skip_accept_encoding=True)  # fmt: skip
                for name, value in request.headers.raw:
                    conn.putheader(name.decode("latin-1"), value.decode("latin-1"))
                conn.endheaders(body or None)
            except TimeoutError as err:
                raise httpx.WriteTimeout(str(err) or "write timed out") from err
            except (http.client.HTTPException, OSError) as err:
                raise httpx.WriteError(f"{type(err).__name__}: {err}") from err
            conn.sock.settimeout(timeout.get("read"))
            try:
                response = conn.getresponse()
            except TimeoutError as err:
                raise httpx.ReadTimeout(str(err) or "read timed out") from err
            except (http.client.HTTPException, OSError) as err:
                raise _read_error(err) from err
        except BaseException:
            conn.close()
            raise
        return httpx.Response(
            response.status,
            headers=response.getheaders(),
            stream=_BodyStream(self, connection, response),
            extensions={
                "http_version": b"HTTP/1.1" if response.version == 11 else b"HTTP/1.0",
                "reason_phrase": response.reason.encode("latin-1", "replace"),
            },  # fmt: skip
        )

    def quick_get(
        self, url: httpx.URL, head: bytes, timeout: Mapping[str, float | None], *, max_bytes: int, total_s: float
    ) -> tuple[int, bytes] | None:
        """Send ``head`` (a whole ``GET`` request head, ending in the empty line) to ``url``'s camera on a kept-alive
        connection and read the reply straight off the socket (see the module docstring's *quick path*).

        Returns ``(status, body)`` of a reply framed by ``Content-Length``, without content coding and not
        ``multipart/*`` (the body of a non-2xx reply is read only to keep the connection: it may be empty);
        None for any other reply (its connection closed): the caller asks again through :meth:`handle_request`.
        Connect/read/write failures and timeouts raise the ``httpx`` exceptions :meth:`handle_request` raises;
        ``total_s`` bounds the whole reply (a trickling reply ends in ``ReadTimeout``).
        """
        connection = self._take(url, timeout)
        conn = connection.conn
        try:
            _connect(connection)
            sock = conn.sock
            assert sock is not None  # noqa: S101 - connected above
            sock.settimeout(timeout.get("write"))
            try:
                sock.sendall(head)
            except TimeoutError as err:
                raise httpx.WriteTimeout(str(err) or "write timed out") from err
            except OSError as err:
                raise httpx.WriteError(f"{type(err).__name__}: {err}") from err
            sock.settimeout(timeout.get("read"))
            reply = _read_reply(sock, max_bytes, time.monotonic() + total_s)
        except BaseException:
            conn.close()
            raise
        if reply is None or not reply.reusable:
            conn.close()
        else:
            self._release(connection)
        return None if reply is None else (reply.status, reply.body)

    def close(self) -> None:
        """Close the idle connections (a response still being read closes its own)."""
        with self._lock:
            self._closed = True
            idle, self._idle = self._idle, []
        for connection in idle:
            connection.conn.close()
