"""The web console's HTTP side (ROS-free): newest-frame slots, MJPEG streaming, JSON API, token check.

One :class:`ConsoleServer` (a stdlib ``ThreadingHTTPServer``) runs in one managed thread and talks to the ROS
side only through a :class:`ConsoleBackend` (the ``axis_web_console`` node implements it). Video is passed
through: the JPEG bytes of a ``CompressedImage`` go to every watching client unchanged, each client always
gets the newest frame (a slow client skips frames, nothing queues), and the backend is told when the first
client starts / the last client stops watching a stream so it subscribes to a topic only while it is watched.

Security: by default the server binds 127.0.0.1 and checks the ``Host`` header (no DNS rebinding); binding
any other address requires a token, and then every request must carry it (``Authorization: Bearer``,
``X-Axis-Token`` or the ``axis_token`` cookie set by the login form), and HTTPS (:mod:`.tls`; plain HTTP off
loopback only when explicitly allowed). Wrong tokens are throttled per client network on every path
(:mod:`.auth`). POSTs must be ``application/json`` and same-origin (no cross-site request forgery from another
page in the operator's browser). Every malformed request gets a 4xx answer. The token is never logged, echoed
or put into a URL; the cookie is ``HttpOnly; SameSite=Strict`` (and ``Secure`` over HTTPS).
"""

from __future__ import annotations

import ipaddress
import json
import math
import select
import socket
import ssl
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from dataclasses import dataclass, field
from html import escape as html_escape
from http import HTTPStatus
from http.cookies import SimpleCookie
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any, Protocol
from urllib.parse import parse_qs, quote, unquote, urlsplit

from axis_ptz_ros2.vapix.mjpeg import multipart_content_type, part_header
from axis_ptz_ros2.web.api import COMMANDS as COMMAND_FIELDS
from axis_ptz_ros2.web.api import STREAM_NAMES, BadRequest
from axis_ptz_ros2.web.api import integer as integer  # re-exported for callers of this module
from axis_ptz_ros2.web.api import number as number
from axis_ptz_ros2.web.auth import AuthThrottle, token_matches
from axis_ptz_ros2.web.h264relay import CONTENT_TYPE as H264_CONTENT_TYPE
from axis_ptz_ros2.web.h264relay import H264Slot, encode_record
from axis_ptz_ros2.web.tls import TlsIdentity, load_identity

STATIC_DIR = Path(__file__).resolve().parent / "static"
STATIC_TYPES = {
    ".html": "text/html; charset=utf-8",
    ".js": "text/javascript; charset=utf-8",
    ".css": "text/css; charset=utf-8",
    ".svg": "image/svg+xml",
    ".png": "image/png",
}
BOUNDARY = "axisframe"
COOKIE = "axis_token"
MAX_BODY = 64 * 1024
#: s, longest wait for the next frame of a stream before checking whether its client hung up
STREAM_POLL_S = 0.5
STREAMS = STREAM_NAMES
COMMANDS = tuple(COMMAND_FIELDS)


# ---------------------------------------------------------------------------------------------------------
# Newest-frame slot
# ---------------------------------------------------------------------------------------------------------
class FrameSlot:
    """The newest JPEG of one stream, shared by all HTTP clients; counts watchers.

    ``on_watchers`` is called (from an HTTP thread, outside the lock) whenever the watcher count goes
    0 → 1 or 1 → 0, so the owner can subscribe/unsubscribe.
    """

    def __init__(self, name: str, on_watchers: Callable[[str, int], None] | None = None) -> None:
        self.name = name
        self._cond = threading.Condition()
        self._seq = 0
        self._jpeg = b""
        self._arrival = 0.0
        self._watchers = 0
        self._on_watchers = on_watchers
        self._closed = False

    def publish(self, jpeg: bytes) -> None:
        """Store a new frame (bytes object kept as is: no copy, no re-encode) and wake the watchers."""
        with self._cond:
            self._seq += 1
            self._jpeg = jpeg
            self._arrival = time.monotonic()
            self._cond.notify_all()

    def latest(self) -> tuple[int, bytes, float]:
        """(sequence number, JPEG bytes, monotonic arrival time) of the newest frame (seq 0 = none yet)."""
        with self._cond:
            return self._seq, self._jpeg, self._arrival

    def wait_newer(self, seq: int, timeout: float) -> tuple[int, bytes] | None:
        """Block until a frame newer than ``seq`` exists (or timeout / close); return the newest one."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while self._seq <= seq and not self._closed:
                left = deadline - time.monotonic()
                if left <= 0:
                    return None
                self._cond.wait(left)
            if self._seq <= seq:
                return None
            return self._seq, self._jpeg

    @property
    def watchers(self) -> int:
        """HTTP clients currently watching this stream."""
        with self._cond:
            return self._watchers

    @contextmanager
    def watch(self) -> Iterator[None]:
        """Count one watcher for the duration of the ``with`` block."""
        with self._cond:
            self._watchers += 1
            n = self._watchers
        if n == 1 and self._on_watchers:
            self._on_watchers(self.name, n)
        try:
            yield
        finally:
            with self._cond:
                self._watchers -= 1
                n = self._watchers
            if n == 0 and self._on_watchers:
                self._on_watchers(self.name, n)

    def close(self) -> None:
        """Wake every waiter for good (server shutdown)."""
        with self._cond:
            self._closed = True
            self._cond.notify_all()


# ---------------------------------------------------------------------------------------------------------
# Backend interface
# ---------------------------------------------------------------------------------------------------------
@dataclass
class CommandResult:
    """Outcome of an operator command: HTTP status, ``ok`` and a human-readable message (+ extra fields)."""

    ok: bool
    message: str
    status: int = 200
    extra: dict[str, Any] = field(default_factory=dict)

    def body(self) -> dict[str, Any]:
        """The JSON answer ``{ok, message, ...}``."""
        return {"ok": self.ok, "message": self.message, **self.extra}


class ConsoleBackend(Protocol):
    """What the HTTP side needs from the ROS side."""

    def slot(self, name: str) -> FrameSlot | None:
        """The frame slot of stream ``name`` (``ptz``, ``panorama``, ``overlay``), or None if not served."""

    def h264_slot(self, name: str) -> H264Slot | None:
        """The H.264 relay of stream ``name`` (only ``ptz``), or None if not served."""

    def state(self) -> dict[str, Any]:
        """Everything the page shows (JSON-serialisable)."""

    def keymap(self) -> dict[str, Any]:
        """The keyboard teleop key map as JSON (one table drives the terminal teleop and the page)."""

    def command(self, name: str, body: dict[str, Any]) -> CommandResult:
        """Run one of :data:`COMMANDS` (may raise :class:`BadRequest`); must return within a bounded time."""


def is_loopback(host: str) -> bool:
    """True for 127.0.0.0/8, ::1 and ``localhost``."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


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


class ConsoleHandler(BaseHTTPRequestHandler):
    """Routes of the console (see the module docstring and :data:`ROUTES`)."""

    server: ConsoleServer
    protocol_version = "HTTP/1.1"
    server_version = "axis_web_console/1"
    default_request_version = "HTTP/1.0"  # errors on unparsable request lines still get a status line
    timeout = 30.0  # s, a client that neither sends nor reads for this long is dropped

    # -- plumbing -----------------------------------------------------------------------------------
    def log_message(self, format: str, *args: Any) -> None:  # noqa: A002 - stdlib signature
        """Quiet by default (request lines never carry secrets here, but the log is the node's business)."""

    def __getattr__(self, name: str) -> Any:  # noqa: ANN401 - handler methods
        """Any method we do not serve (PUT, DELETE, BREW, …) gets 405, not the stdlib's 501."""
        if name.startswith("do_"):
            return self._method_not_allowed
        raise AttributeError(name)

    def send_error(self, code: int, message: str | None = None, explain: str | None = None) -> None:
        """The stdlib's own refusals (bad request line, header too long, …) as JSON with a reason, like ours.

        An HTTP version the console does not speak is a 400 too (the stdlib's 505 is the only 5xx it sends).
        """
        if code == HTTPStatus.HTTP_VERSION_NOT_SUPPORTED:
            code, message = HTTPStatus.BAD_REQUEST, "only HTTP/1.0 and HTTP/1.1 are served"
        self.close_connection = True
        self._unread_body = True  # the rest of the connection is not a request we understood
        text = message or HTTPStatus(code).phrase
        self.command = getattr(self, "command", None) or ""  # before parse_request it may not exist yet
        if not getattr(self, "request_version", ""):
            self.request_version = self.default_request_version
        self._error(code, text[:200])

    def _method_not_allowed(self) -> None:
        self._unread_body = True  # whatever body it has is not read: close after answering
        self._send(
            HTTPStatus.METHOD_NOT_ALLOWED,
            json.dumps({"ok": False, "message": f"method {self.command[:20]!r} not allowed"}).encode(),
            "application/json",
            {"Allow": "GET, HEAD, POST"},
        )

    def parse_request(self) -> bool:
        """The stdlib's parsing plus a strict ``Content-Length`` (digits only, one value, no chunked bodies)."""
        self._unread_body = False
        self._body_len = 0
        words = str(self.raw_requestline, "iso-8859-1").split()
        if len(words) == 2:  # HTTP/0.9 ("GET /"): answer now; the stdlib would wait for headers that never come
            self.command, self.request_version, self.requestline = "", "HTTP/1.0", " ".join(words)[:100]
            self.close_connection = True
            self._error(HTTPStatus.BAD_REQUEST, "HTTP/0.9 requests are not served: send HTTP/1.1 with a Host header")
            return False
        if not super().parse_request():
            return False
        if len(self.requestline.split()) != 3 or self.request_version not in ("HTTP/1.0", "HTTP/1.1"):
            # HTTP/0.9 has no headers (no Host, no token) and would be answered without a status line; a
            # request line that only names it ("X Y HTTP/0.9") gets a real status line too
            self.request_version, self.close_connection = "HTTP/1.0", True
            self._error(HTTPStatus.BAD_REQUEST, "only HTTP/1.0 and HTTP/1.1 are served")
            return False
        if self.headers.get("Transfer-Encoding"):
            self._unread_body = True
            self._error(HTTPStatus.LENGTH_REQUIRED, "chunked bodies are not accepted: send Content-Length")
            return False
        values = self.headers.get_all("Content-Length") or []
        if values:
            v = values[0].strip()
            if not v.isascii() or not v.isdigit() or any(x.strip() != v for x in values) or len(v) > 18:
                self._unread_body = True
                self._error(HTTPStatus.BAD_REQUEST, "malformed Content-Length")
                return False
            self._body_len = int(v)
            self._unread_body = self._body_len > 0
        return True

    def _read_body(self) -> bytes | None:
        """The request body (≤ MAX_BODY); answers 413 / 408 itself and returns None on failure."""
        n = self._body_len
        if n > MAX_BODY:
            self._error(HTTPStatus.REQUEST_ENTITY_TOO_LARGE, f"request body too large (max {MAX_BODY} bytes)")
            return None
        if n == 0:
            return b""
        old = self.connection.gettimeout()
        self.connection.settimeout(self.server.io_timeout)
        try:
            raw = self.rfile.read(n)
        except (TimeoutError, OSError):
            raw = b""
        finally:
            with suppress(OSError):
                self.connection.settimeout(old)
        if len(raw) != n:
            self._error(HTTPStatus.REQUEST_TIMEOUT, "request body shorter than its Content-Length")
            return None
        self._unread_body = False
        return raw

    def _send(self, status: int, body: bytes, ctype: str, headers: dict[str, str] | None = None) -> None:
        if self._unread_body:  # the rest of this request is still in the socket: never parse it as a request
            self.close_connection = True
            headers = {**(headers or {}), "Connection": "close"}
        self.send_response(status)
        self.send_header("Content-Type", ctype)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.send_header("X-Content-Type-Options", "nosniff")
        # same-origin, not no-referrer: with no-referrer browsers send "Origin: null" on form posts, which the
        # same-origin check must refuse (the sign-in form then never worked in a browser)
        self.send_header("Referrer-Policy", "same-origin")
        for k, v in (headers or {}).items():
            self.send_header(k, v)
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(body)

    def _json(self, status: int, obj: Any) -> None:
        self._send(status, json.dumps(obj, allow_nan=False).encode("utf-8"), "application/json")

    def _error(self, status: int, message: str) -> None:
        self._json(status, {"ok": False, "message": message})

    def _presented_token(self) -> tuple[str, str] | None:
        """(where, token) of the credential this request presents (Bearer, X-Axis-Token or cookie), if any."""
        auth = self.headers.get("Authorization", "")
        if auth.lower().startswith("bearer "):
            return "bearer", auth[7:].strip()
        if self.headers.get("X-Axis-Token"):
            return "header", self.headers["X-Axis-Token"].strip()
        raw = self.headers.get("Cookie")
        if raw:
            c: SimpleCookie = SimpleCookie()
            with suppress(Exception):  # noqa: BLE001 - a malformed cookie header is just no token
                c.load(raw)
            if COOKIE in c:
                return "cookie", unquote(c[COOKIE].value)
        return None

    @property
    def _client(self) -> str:
        return str(self.client_address[0]) if self.client_address else "?"

    def _host_ok(self) -> bool:
        """On a loopback bind, only loopback Host names (defeats DNS rebinding); everywhere one sane Host."""
        hosts = self.headers.get_all("Host") or []
        if len(hosts) > 1:
            return False
        host = hosts[0].strip() if hosts else ""
        if not is_loopback(self.server.bind):
            return bool(host) or self.request_version == "HTTP/1.0"
        name = host.rsplit(":", 1)[0] if not host.endswith("]") else host
        return is_loopback(name)

    def _refuse_host(self) -> bool:
        """Answer 421 for an unacceptable Host header; True when refused."""
        if self._host_ok():
            return False
        self._error(HTTPStatus.MISDIRECTED_REQUEST, "unexpected Host header")
        return True

    def _throttled(self, page: bool = False) -> bool:
        """Answer 429 when this address has guessed too often; True when refused."""
        wait = self.server.throttle.retry_after(self._client)
        if wait <= 0:
            return False
        secs = str(max(1, math.ceil(wait)))
        text = f"too many wrong tokens from this network: try again in {secs} s"
        if page:
            self._login_page(text.capitalize() + ".", HTTPStatus.TOO_MANY_REQUESTS, {"Retry-After": secs})
        else:
            body = json.dumps({"ok": False, "message": text}).encode("utf-8")
            self._send(HTTPStatus.TOO_MANY_REQUESTS, body, "application/json", {"Retry-After": secs})
        return True

    def _cookie(self, value: str, max_age: int | None = None) -> str:
        """The session cookie: HttpOnly, SameSite=Strict, and Secure whenever the console speaks HTTPS."""
        c = f"{COOKIE}={value}; HttpOnly; SameSite=Strict; Path=/"
        if self.server.tls is not None:
            c += "; Secure"
        if max_age is not None:
            c += f"; Max-Age={max_age}"
        return c

    def _origin_ok(self) -> bool:
        origin = self.headers.get("Origin")
        if origin is None or origin == "null":
            return origin is None
        return urlsplit(origin).netloc == self.headers.get("Host", "")

    def _guard(self, page: bool = False) -> bool:
        """Host, throttle and token checks; answers the refusal itself and returns False when refused."""
        if self._refuse_host():
            return False
        if self.server.token is None:
            return True
        presented = self._presented_token()
        if presented is not None and self._throttled(page):
            return False  # a guess while locked out is not even compared
        if presented is not None and self.server.token_ok(presented[1]):
            return True
        headers: dict[str, str] = {}
        if presented is not None:
            self.server.throttle.failed(self._client)
            if presented[0] == "cookie":  # a stale cookie must not keep costing the browser guesses
                headers["Set-Cookie"] = self._cookie("", max_age=0)
        if page:
            self._login_page("Wrong or expired token." if presented else "", headers=headers)
        else:
            body = json.dumps({"ok": False, "message": "token required"}).encode("utf-8")
            self._send(HTTPStatus.UNAUTHORIZED, body, "application/json", headers)
        return False

    def _login_page(
        self, message: str = "", status: int = HTTPStatus.UNAUTHORIZED, headers: dict[str, str] | None = None
    ) -> None:
        note = f"<p role='alert'>{html_escape(message)}</p>" if message else ""
        html = (
            "<!doctype html><html lang='en'><head><meta charset='utf-8'><title>Axis PTZ console: sign in</title>"
            "<link rel='stylesheet' href='/static/style.css'></head><body class='login'><main>"
            "<h1>Axis PTZ console</h1>" + note + "<form method='post' action='/login'>"
            "<label for='token'>Access token</label> <input id='token' name='token' type='password'"
            " autocomplete='current-password' required> <button type='submit'>Sign in</button></form>"
            "</main></body></html>"
        )
        self._send(status, html.encode("utf-8"), "text/html; charset=utf-8", headers)

    # -- GET ----------------------------------------------------------------------------------------
    def do_HEAD(self) -> None:
        """Like GET without a body (not for video)."""
        if urlsplit(self.path).path.startswith("/video/"):
            self._error(HTTPStatus.METHOD_NOT_ALLOWED, "HEAD is not served for video")
            return
        self.do_GET()

    def do_GET(self) -> None:
        """Page, static files, video streams, snapshots, state, key map."""
        path = urlsplit(self.path).path
        if path == "/login":
            if not self._refuse_host():
                self._login_page()
            return
        if path in ("/", "/index.html"):
            if self._guard(page=True):
                self._static("index.html")
            return
        if path.startswith("/static/"):
            # style.css is served to the login page too; everything else needs the token
            name = path[len("/static/") :]
            if name == "style.css":
                if not self._refuse_host():
                    self._static(name)
            elif self._guard():
                self._static(name)
            return
        if not self._guard():
            return
        if path == "/api/state":
            self._json(HTTPStatus.OK, self.server.backend.state())
        elif path == "/api/keymap":
            self._json(HTTPStatus.OK, self.server.backend.keymap())
        elif path.startswith("/video/") and path.endswith(".mjpg"):
            self._mjpeg(path[len("/video/") : -len(".mjpg")])
        elif path.startswith("/video/") and path.endswith(".h264"):
            self._h264(path[len("/video/") : -len(".h264")])
        elif path.startswith("/video/") and path.endswith(".jpg"):
            q = parse_qs(urlsplit(self.path).query)
            self._snapshot(path[len("/video/") : -len(".jpg")], fresh="fresh" in q)
        else:
            self._error(HTTPStatus.NOT_FOUND, f"no such resource {path}")

    def _static(self, name: str) -> None:
        d = self.server.static_dir
        # only plain file names of the static folder (no traversal, no sub-folders)
        if "/" in name or "\\" in name or name.startswith(".") or Path(name).suffix not in STATIC_TYPES:
            self._error(HTTPStatus.NOT_FOUND, "not found")
            return
        p = d / name
        if not p.is_file():
            self._error(HTTPStatus.NOT_FOUND, "not found")
            return
        headers = {
            "Content-Security-Policy": "default-src 'self'; img-src 'self' blob:; object-src 'none'; "
            "base-uri 'none'; frame-ancestors 'none'; form-action 'self'"
        }
        self._send(HTTPStatus.OK, p.read_bytes(), STATIC_TYPES[p.suffix], headers)

    def _slot_or_404(self, name: str) -> FrameSlot | None:
        slot = self.server.backend.slot(name) if name in STREAMS else None
        if slot is None:
            self._error(HTTPStatus.NOT_FOUND, f"no stream {name!r}")
        return slot

    def _snapshot(self, name: str, fresh: bool) -> None:
        """The newest frame as one JPEG (waits up to 5 s for a frame while watching the stream)."""
        slot = self._slot_or_404(name)
        if slot is None:
            return
        with slot.watch():
            seq, jpeg, _ = slot.latest()
            if fresh or seq == 0:
                got = slot.wait_newer(seq, 5.0)
                if got is None:
                    self._error(HTTPStatus.SERVICE_UNAVAILABLE, f"no new frame on stream {name!r}")
                    return
                seq, jpeg = got
        self._send(HTTPStatus.OK, jpeg, "image/jpeg")

    def _mjpeg(self, name: str) -> None:
        """multipart/x-mixed-replace stream of the newest frames until the client or the server goes."""
        slot = self._slot_or_404(name)
        if slot is None:
            return
        self._stream_head(multipart_content_type(BOUNDARY), sndbuf=64 * 1024)
        with slot.watch():
            seq = 0

            def parts(timeout: float) -> tuple[bytes, ...] | None:
                nonlocal seq
                got = slot.wait_newer(seq, timeout)
                if got is None:
                    return None
                seq, jpeg = got
                return part_header(BOUNDARY, len(jpeg)), jpeg, b"\r\n"

            self._relay(parts)

    def _h264(self, name: str) -> None:
        """The H.264 access units of a stream as length-prefixed records (:mod:`.h264relay`) until either side
        goes."""
        get = getattr(self.server.backend, "h264_slot", None)
        slot = get(name) if get is not None and name in STREAMS else None
        if slot is None:
            self._error(HTTPStatus.NOT_FOUND, f"no H.264 stream {name!r}")
            return
        self._stream_head(H264_CONTENT_TYPE, sndbuf=256 * 1024)
        with slot.watch() as client:

            def parts(timeout: float) -> tuple[bytes, ...] | None:
                got = slot.next(client, timeout)
                return None if got is None else (encode_record(got[0], catch_up=got[1]),)

            self._relay(parts)

    def _stream_head(self, ctype: str, sndbuf: int) -> None:
        """The response head of an endless stream (it ends with the connection), after shrinking the socket's
        send buffer to ``sndbuf`` bytes: the kernel's send queue stays short, so a slow client drops frames."""
        with suppress(OSError):
            self.connection.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, sndbuf)
        self.send_response(HTTPStatus.OK)
        self.send_header("Content-Type", ctype)
        self.send_header("Cache-Control", "no-store")
        self.send_header("Connection", "close")
        self.send_header("X-Content-Type-Options", "nosniff")
        self.end_headers()
        self.wfile.flush()
        self.close_connection = True

    def _relay(self, parts: Callable[[float], tuple[bytes, ...] | None]) -> None:
        """Write what ``parts(timeout)`` gives (the pieces of the next frame, None when nothing came within
        ``timeout``) until the server stops or the client goes: a failed write, or a hang-up noticed while no
        frame arrives (so idle streams end too)."""
        stop = self.server.stop_event
        try:
            while not stop.is_set():
                pieces = parts(STREAM_POLL_S)
                if pieces is None:
                    if self._client_gone():
                        return
                    continue
                for piece in pieces:
                    self.wfile.write(piece)
                self.wfile.flush()
        except (OSError, ValueError):  # client went away (BrokenPipe, reset, timeout, closed file)
            return

    def _client_gone(self) -> bool:
        """True when the client closed its end (checked while no frame arrives, so idle streams end too)."""
        conn = self.connection
        try:
            if isinstance(conn, ssl.SSLSocket):
                if not conn.pending():
                    readable, _, _ = select.select([conn], [], [], 0)
                    if not readable:
                        return False
                old = conn.gettimeout()
                conn.settimeout(0.0)
                try:
                    return conn.recv(1) == b""  # TLS records (close_notify, key update) or EOF
                except (ssl.SSLWantReadError, ssl.SSLWantWriteError):
                    return False
                finally:
                    conn.settimeout(old)
            readable, _, _ = select.select([conn], [], [], 0)
            if not readable:
                return False
            return bool(conn.recv(1, socket.MSG_PEEK) == b"")
        except (OSError, ValueError):
            return True

    # -- POST ---------------------------------------------------------------------------------------
    def do_POST(self) -> None:
        """Login form and JSON commands."""
        path = urlsplit(self.path).path
        if self._refuse_host():
            return
        if not self._origin_ok():
            self._error(HTTPStatus.FORBIDDEN, "cross-origin request refused")
            return
        raw = self._read_body()
        if raw is None:
            return
        if path == "/login":
            self._login(raw)
            return
        if not self._guard():
            return
        if not path.startswith("/api/") or path[len("/api/") :] not in COMMANDS:
            self._error(HTTPStatus.NOT_FOUND, f"no such command {path}")
            return
        ctype = self.headers.get("Content-Type", "").split(";")[0].strip().lower()
        if ctype != "application/json":
            self._error(HTTPStatus.UNSUPPORTED_MEDIA_TYPE, "commands must be application/json")
            return
        try:
            body = json.loads(raw.decode("utf-8") or "{}")
        except (ValueError, RecursionError) as err:  # bad UTF-8, bad JSON, absurd numbers, absurd nesting
            self._error(HTTPStatus.BAD_REQUEST, f"invalid JSON: {str(err)[:200]}")
            return
        if not isinstance(body, dict):
            self._error(HTTPStatus.BAD_REQUEST, "body must be a JSON object")
            return
        try:
            result = self.server.backend.command(path[len("/api/") :], body)
        except BadRequest as err:
            self._error(HTTPStatus.BAD_REQUEST, str(err))
            return
        except Exception as err:  # noqa: BLE001 - a bug behind one command must not leave the client hanging
            if self.server.log:
                self.server.log(f"command {path} failed: {type(err).__name__}: {err}")
            self._error(HTTPStatus.INTERNAL_SERVER_ERROR, f"internal error: {type(err).__name__}")
            return
        self._json(result.status, result.body())

    def _login(self, raw: bytes) -> None:
        if self.server.token is None:
            self._send(HTTPStatus.SEE_OTHER, b"", "text/plain", {"Location": "/"})
            return
        if self._throttled(page=True):
            return
        form = parse_qs(raw.decode("utf-8", "replace"))
        presented = (form.get("token") or [""])[0]
        if not self.server.token_ok(presented):
            self.server.throttle.failed(self._client)
            self._login_page("Wrong token.")
            return
        cookie = self._cookie(quote(presented, safe=""))
        self._send(HTTPStatus.SEE_OTHER, b"", "text/plain", {"Location": "/", "Set-Cookie": cookie})
