"""The web console's HTTP server (ROS-free): lifecycle, TLS per connection, the backend interface, :func:`serve`.

One :class:`ConsoleServer` (a stdlib ``ThreadingHTTPServer``) runs in one managed thread and talks to the ROS
side only through a :class:`.backend.ConsoleBackend` (the ``axis_web_console`` node implements it). Each connection gets
its own thread: the TLS handshake (when serving HTTPS), then one :class:`.handler.ConsoleHandler` (strict parsing,
Host/token/origin guards, the routes); video goes out through :mod:`.relay` (newest-frame slots, MJPEG) and
:mod:`.h264relay`. Which hosts are loopback: :mod:`.loopback`.

Security: by default the server binds 127.0.0.1 (the handler then answers only loopback ``Host`` names: no DNS
rebinding); binding any other address requires a token, which every request must then carry, and HTTPS
(:mod:`.tls`; plain HTTP off loopback only when explicitly allowed). Wrong tokens are throttled per client network
(:mod:`.auth`); the token is never logged, echoed or put into a URL.
"""

from __future__ import annotations

import socket
import ssl
import sys
import threading
import time
from collections.abc import Callable
from contextlib import suppress
from http.server import ThreadingHTTPServer
from pathlib import Path
from typing import Any

from axis_ptz_ros2.web.auth import AuthThrottle, token_matches
from axis_ptz_ros2.web.backend import ConsoleBackend
from axis_ptz_ros2.web.handler import ConsoleHandler, ConsoleHost
from axis_ptz_ros2.web.loopback import is_loopback
from axis_ptz_ros2.web.tls import TlsIdentity, load_identity

STATIC_DIR = Path(__file__).resolve().parent / "static"


# ---------------------------------------------------------------------------------------------------------
# Server
# ---------------------------------------------------------------------------------------------------------
def needs_tls(bind: str, allow_plain_http: bool, tls_on_loopback: bool = False) -> bool:
    """HTTPS off loopback unless plain HTTP is explicitly allowed; on loopback only when asked for."""
    if is_loopback(bind):
        return tls_on_loopback
    return not allow_plain_http


class ConsoleServer(ThreadingHTTPServer):
    """``ThreadingHTTPServer`` bound to ``(bind, port)`` serving a :class:`ConsoleBackend` (HTTP or HTTPS)."""

    daemon_threads = True
    allow_reuse_address = True
    #: s, longest wait for a TLS handshake or for a request body announced by Content-Length
    io_timeout = 10.0

    def __init__(
        self,
        backend: ConsoleBackend,
        bind: str = "127.0.0.1",
        port: int = 0,
        token: str | None = None,
        static_dir: Path = STATIC_DIR,
        log: Callable[[str], None] | None = None,
        tls: TlsIdentity | None = None,
        allow_plain_http: bool = False,
        throttle: AuthThrottle | None = None,
        debug: Callable[[str], None] | None = None,
    ) -> None:
        if not is_loopback(bind) and not token:
            raise ValueError(
                f"refusing to serve the console on {bind!r} without a token: set AXIS_WEB_TOKEN or token_file,"
                " or bind 127.0.0.1"
            )
        if not is_loopback(bind) and tls is None and not allow_plain_http:
            raise ValueError(
                f"refusing to serve the console on {bind!r} over plain HTTP (the token would cross the network in"
                " clear): give a TLS certificate (or let one be generated), or set allow_plain_http"
            )
        self.address_family = socket.AF_INET6 if ":" in bind else socket.AF_INET
        self.backend = backend
        self.token = token or None
        self.static_dir = static_dir
        self.log = log
        self.debug = debug
        self.tls = tls
        #: clients that hung up before their answer was complete (counted, logged at debug level only)
        self.clients_gone = 0
        #: requests that failed inside the server (a bug: logged as one line, never a traceback)
        self.handler_errors = 0
        self.throttle = throttle or AuthThrottle()
        self.stop_event = threading.Event()
        self._conns: set[socket.socket] = set()
        self._conns_lock = threading.Lock()
        self._thread: threading.Thread | None = None
        super().__init__((bind, port), ConsoleHandler)
        self.port = int(self.server_address[1])
        self.bind = bind

    @property
    def scheme(self) -> str:
        """``https`` or ``http``."""
        return "https" if self.tls is not None else "http"

    @property
    def url(self) -> str:
        """``http(s)://HOST:PORT/`` of the bound socket."""
        host = f"[{self.bind}]" if ":" in self.bind else self.bind
        if self.bind in ("0.0.0.0", "::"):
            host = "127.0.0.1"
        return f"{self.scheme}://{host}:{self.port}/"

    # -- lifecycle ----------------------------------------------------------------------------------
    def start(self) -> None:
        """Serve in one background thread."""
        self._thread = threading.Thread(
            target=self.serve_forever, kwargs={"poll_interval": 0.2}, name="axis_web_console_http", daemon=True
        )
        self._thread.start()

    def stop(self, timeout: float = 3.0) -> None:
        """Stop serving, end every open stream (closing slow clients' sockets), release the port."""
        self.stop_event.set()
        if self._thread is not None:
            self.shutdown()
            self._thread.join(timeout)
        with self._conns_lock:
            conns = list(self._conns)
        for c in conns:
            with suppress(OSError, ValueError):
                c.shutdown(socket.SHUT_RDWR)
        # handler threads are daemons that the server does not join: let them return (their sockets are shut,
        # a ROS service call ends within service_timeout) before the caller destroys the node they call into
        deadline = time.monotonic() + timeout
        while self.open_connections and time.monotonic() < deadline:
            time.sleep(0.01)
        self.server_close()

    def finish_request(self, request: Any, client_address: Any) -> None:
        """Per connection (in its own thread): TLS handshake when serving HTTPS, then the HTTP handler.

        The handshake runs here, not in the accepting thread, so a client that connects and stays silent
        holds only its own thread (for at most :attr:`io_timeout`). A plain HTTP request to the HTTPS port is
        answered with a 400 that says so.
        """
        conn: socket.socket = request
        if self.tls is not None:
            conn.settimeout(self.io_timeout)
            try:
                first = conn.recv(1, socket.MSG_PEEK)
            except OSError:
                return
            if not first:
                return
            if first != b"\x16":  # not a TLS handshake record: most likely plain HTTP
                body = b"This console speaks HTTPS only: use https:// in the address.\n"
                with suppress(OSError):
                    conn.sendall(
                        b"HTTP/1.1 400 Bad Request\r\nContent-Type: text/plain; charset=utf-8\r\n"
                        b"Connection: close\r\nContent-Length: " + str(len(body)).encode() + b"\r\n\r\n" + body
                    )
                return
            try:
                conn = self.tls.context.wrap_socket(conn, server_side=True)
            except (ssl.SSLError, OSError):
                return  # failed handshake (untrusted certificate, wrong protocol, timeout): nothing to answer
            conn.settimeout(None)
        with self._conns_lock:
            self._conns.add(conn)
        try:
            ConsoleHandler(conn, client_address, self)
        finally:
            with self._conns_lock:
                self._conns.discard(conn)
            if conn is not request:
                with suppress(OSError):
                    conn.shutdown(socket.SHUT_WR)
                conn.close()

    def handle_error(self, request: Any, client_address: Any) -> None:
        """A handler raised: a client that hung up is counted quietly; anything else is one error line.

        (The stdlib prints a traceback to stderr here: anyone reaching the port could flood the log with them.)
        """
        err = sys.exc_info()[1]
        who = client_address[0] if isinstance(client_address, tuple) and client_address else "?"
        if isinstance(err, ConnectionError | TimeoutError | ssl.SSLError):
            with self._conns_lock:
                self.clients_gone += 1
            if self.debug:
                self.debug(f"client {who} went away before its answer: {type(err).__name__}")
            return
        with self._conns_lock:
            self.handler_errors += 1
        if self.log:
            self.log(f"request from {who} failed: {type(err).__name__}: {str(err)[:200]}")

    def counters(self) -> dict[str, int]:
        """Open connections, clients gone before their answer, failed requests (for the page and tests)."""
        with self._conns_lock:
            return {"open": len(self._conns), "clients_gone": self.clients_gone, "errors": self.handler_errors}

    @property
    def open_connections(self) -> int:
        """HTTP connections currently open (for tests and diagnostics)."""
        with self._conns_lock:
            return len(self._conns)

    # -- auth ---------------------------------------------------------------------------------------
    def token_ok(self, presented: str | None) -> bool:
        """Constant-time comparison with the configured token (True when no token is configured)."""
        if self.token is None:
            return True
        if not presented:
            return False
        return token_matches(presented, self.token)


#: (for mypy) a ConsoleServer is what a :class:`ConsoleHandler` needs of its server
_SERVER_IS_A_HOST: type[ConsoleHost] = ConsoleServer


def serve(
    backend: ConsoleBackend,
    *,
    bind: str,
    port: int,
    token: str | None,
    tls_files: tuple[str, str, str] = ("", "", ""),
    allow_plain_http: bool = False,
    tls_on_loopback: bool = False,
    throttle: AuthThrottle | None = None,
    info: Callable[[str], None] = print,
    warn: Callable[[str], None] = print,
    error: Callable[[str], None] | None = None,
    debug: Callable[[str], None] | None = None,
) -> ConsoleServer:
    """Start a console: HTTPS when :func:`needs_tls` (``tls_files`` = certificate, key, directory for a generated
    one), the URL and the certificate's fingerprint reported through ``info``."""
    tls: TlsIdentity | None = None
    if needs_tls(bind, allow_plain_http, tls_on_loopback):
        tls = load_identity(tls_files[0], tls_files[1], bind, tls_files[2])
    elif not is_loopback(bind):
        warn(f"allow_plain_http: serving plain HTTP on {bind}: the token crosses the network unencrypted")
    server = ConsoleServer(
        backend, bind=bind, port=port, token=token, tls=tls, allow_plain_http=allow_plain_http, throttle=throttle,
        log=error, debug=debug,
    )  # fmt: skip
    server.start()
    info(f"web console at {server.url} ({'token required' if token else 'no token (loopback only)'})")
    if tls is not None:
        origin = "generated self-signed" if tls.generated else "given"
        where = f", {tls.cert_path}" if tls.cert_path else ""
        info(f"HTTPS certificate ({origin}{where}) SHA-256 fingerprint {tls.fingerprint}")
    return server
