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
"""

from __future__ import annotations

import http.client
import select
import ssl
import threading
from collections.abc import Iterator

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

    def _new(self, url: httpx.URL, timeout: dict[str, float | None]) -> _Connection:
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

    def _take(self, url: httpx.URL, timeout: dict[str, float | None]) -> _Connection:
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
            if not connection.connected:
                try:
                    conn.connect()
                except TimeoutError as err:
                    raise httpx.ConnectTimeout(str(err) or "connect timed out") from err
                except OSError as err:  # refused, unreachable, TLS handshake (ssl.SSLError is an OSError)
                    raise httpx.ConnectError(f"{type(err).__name__}: {err}") from err
                connection.connected = True
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

    def close(self) -> None:
        """Close the idle connections (a response still being read closes its own)."""
        with self._lock:
            self._closed = True
            idle, self._idle = self._idle, []
        for connection in idle:
            connection.conn.close()
