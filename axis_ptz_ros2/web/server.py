"""The web console's HTTP side (ROS-free): newest-frame slots, MJPEG streaming, JSON API, token check.

One :class:`ConsoleServer` (a stdlib ``ThreadingHTTPServer``) runs in one managed thread and talks to the ROS
side only through a :class:`ConsoleBackend` (the ``axis_web_console`` node implements it). Video is passed
through: the JPEG bytes of a ``CompressedImage`` go to every watching client unchanged, each client always
gets the newest frame (a slow client skips frames, nothing queues), and the backend is told when the first
client starts / the last client stops watching a stream so it subscribes to a topic only while it is watched.

Security: by default the server binds 127.0.0.1 and checks the ``Host`` header (no DNS rebinding); binding
any other address requires a token, and then every request must carry it (``Authorization: Bearer``,
``X-Axis-Token`` or the ``axis_token`` cookie set by the login form). POSTs must be ``application/json`` and
same-origin (no cross-site request forgery from another page in the operator's browser). The token is never
logged, echoed or put into a URL.
"""

from __future__ import annotations

import hmac
import ipaddress
import json
import select
import socket
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from dataclasses import dataclass, field
from http import HTTPStatus
from http.cookies import SimpleCookie
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any, Protocol
from urllib.parse import parse_qs, quote, unquote, urlsplit

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
STREAMS = ("ptz", "panorama", "overlay")
COMMANDS = ("center", "look_panorama", "key", "video", "home")


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


class BadRequest(ValueError):  # noqa: N818 - reads as the HTTP status
    """A request body the console cannot use (→ HTTP 400 with the reason)."""


class ConsoleBackend(Protocol):
    """What the HTTP side needs from the ROS side."""

    def slot(self, name: str) -> FrameSlot | None:
        """The frame slot of stream ``name`` (``ptz``, ``panorama``, ``overlay``), or None if not served."""

    def state(self) -> dict[str, Any]:
        """Everything the page shows (JSON-serialisable)."""

    def keymap(self) -> dict[str, Any]:
        """The keyboard teleop key map as JSON (one table drives the terminal teleop and the page)."""

    def command(self, name: str, body: dict[str, Any]) -> CommandResult:
        """Run one of :data:`COMMANDS` (may raise :class:`BadRequest`); must return within a bounded time."""


# ---------------------------------------------------------------------------------------------------------
# Body validation helpers (shared by the node)
# ---------------------------------------------------------------------------------------------------------
def number(body: dict[str, Any], key: str, default: float | None = None) -> float:
    """A finite number from a JSON body, or :class:`BadRequest`."""
    if key not in body or body[key] is None:
        if default is None:
            raise BadRequest(f"missing {key!r}")
        return default
    v = body[key]
    if isinstance(v, bool) or not isinstance(v, int | float):
        raise BadRequest(f"{key!r} must be a number, got {v!r}")
    f = float(v)
    if f != f or f in (float("inf"), float("-inf")):
        raise BadRequest(f"{key!r} must be finite")
    return f


def integer(body: dict[str, Any], key: str, default: int | None = None) -> int:
    """An integer (JSON number without fraction) from a body, or :class:`BadRequest`."""
    f = number(body, key, None if default is None else float(default))
    if f != int(f):
        raise BadRequest(f"{key!r} must be an integer, got {f!r}")
    return int(f)


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
class ConsoleServer(ThreadingHTTPServer):
    """``ThreadingHTTPServer`` bound to ``(bind, port)`` serving a :class:`ConsoleBackend`."""

    daemon_threads = True
    allow_reuse_address = True

    def __init__(
        self,
        backend: ConsoleBackend,
        bind: str = "127.0.0.1",
        port: int = 0,
        token: str | None = None,
        static_dir: Path = STATIC_DIR,
        log: Callable[[str], None] | None = None,
    ) -> None:
        if not is_loopback(bind) and not token:
            raise ValueError(
                f"refusing to serve the console on {bind!r} without a token: set AXIS_WEB_TOKEN or token_file,"
                " or bind 127.0.0.1"
            )
        self.address_family = socket.AF_INET6 if ":" in bind else socket.AF_INET
        self.backend = backend
        self.token = token or None
        self.static_dir = static_dir
        self.log = log
        self.stop_event = threading.Event()
        self._conns: set[socket.socket] = set()
        self._conns_lock = threading.Lock()
        self._thread: threading.Thread | None = None
        super().__init__((bind, port), ConsoleHandler)
        self.port = int(self.server_address[1])
        self.bind = bind

    @property
    def url(self) -> str:
        """``http://HOST:PORT/`` of the bound socket."""
        host = f"[{self.bind}]" if ":" in self.bind else self.bind
        if self.bind in ("0.0.0.0", "::"):
            host = "127.0.0.1"
        return f"http://{host}:{self.port}/"

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
            with suppress(OSError):
                c.shutdown(socket.SHUT_RDWR)
        self.server_close()

    def process_request(self, request: Any, client_address: Any) -> None:
        """Track connections so :meth:`stop` can end streams to clients that stopped reading."""
        with self._conns_lock:
            self._conns.add(request)
        super().process_request(request, client_address)

    def shutdown_request(self, request: Any) -> None:
        """Forget the connection as it closes."""
        with self._conns_lock:
            self._conns.discard(request)
        super().shutdown_request(request)

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
        return hmac.compare_digest(presented.encode("utf-8"), self.token.encode("utf-8"))


class ConsoleHandler(BaseHTTPRequestHandler):
    """Routes of the console (see the module docstring and :data:`ROUTES`)."""

    server: ConsoleServer
    protocol_version = "HTTP/1.1"
    server_version = "axis_web_console/1"
    timeout = 30.0  # s, a client that neither sends nor reads for this long is dropped

    # -- plumbing -----------------------------------------------------------------------------------
    def log_message(self, format: str, *args: Any) -> None:  # noqa: A002 - stdlib signature
        """Quiet by default (request lines never carry secrets here, but the log is the node's business)."""

    def _send(self, status: int, body: bytes, ctype: str, headers: dict[str, str] | None = None) -> None:
        self.send_response(status)
        self.send_header("Content-Type", ctype)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.send_header("X-Content-Type-Options", "nosniff")
        self.send_header("Referrer-Policy", "no-referrer")
        for k, v in (headers or {}).items():
            self.send_header(k, v)
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(body)

    def _json(self, status: int, obj: Any) -> None:
        self._send(status, json.dumps(obj, allow_nan=False).encode("utf-8"), "application/json")

    def _error(self, status: int, message: str) -> None:
        self._json(status, {"ok": False, "message": message})

    def _presented_token(self) -> str | None:
        auth = self.headers.get("Authorization", "")
        if auth.lower().startswith("bearer "):
            return auth[7:].strip()
        if self.headers.get("X-Axis-Token"):
            return self.headers["X-Axis-Token"].strip()
        raw = self.headers.get("Cookie")
        if raw:
            c: SimpleCookie = SimpleCookie()
            with suppress(Exception):  # noqa: BLE001 - a malformed cookie header is just no token
                c.load(raw)
            if COOKIE in c:
                return unquote(c[COOKIE].value)
        return None

    def _host_ok(self) -> bool:
        """On a loopback bind, only loopback Host names (defeats DNS rebinding)."""
        if not is_loopback(self.server.bind):
            return True
        host = self.headers.get("Host", "")
        name = host.rsplit(":", 1)[0] if not host.endswith("]") else host
        return is_loopback(name)

    def _origin_ok(self) -> bool:
        origin = self.headers.get("Origin")
        if origin is None or origin == "null":
            return origin is None
        return urlsplit(origin).netloc == self.headers.get("Host", "")

    def _guard(self, page: bool = False) -> bool:
        """Host and token checks; answers the refusal itself and returns False when refused."""
        if not self._host_ok():
            self._error(HTTPStatus.MISDIRECTED_REQUEST, "unexpected Host header")
            return False
        if not self.server.token_ok(self._presented_token()):
            if page:
                self._login_page()
            else:
                self._error(HTTPStatus.UNAUTHORIZED, "token required")
            return False
        return True

    def _login_page(self, message: str = "") -> None:
        note = f"<p role='alert'>{message}</p>" if message else ""
        html = (
            "<!doctype html><html lang='en'><head><meta charset='utf-8'><title>Axis PTZ console: sign in</title>"
            "<link rel='stylesheet' href='/static/style.css'></head><body class='login'><main>"
            "<h1>Axis PTZ console</h1>" + note + "<form method='post' action='/login'>"
            "<label for='token'>Access token</label> <input id='token' name='token' type='password'"
            " autocomplete='current-password' required> <button type='submit'>Sign in</button></form>"
            "</main></body></html>"
        )
        self._send(HTTPStatus.UNAUTHORIZED, html.encode("utf-8"), "text/html; charset=utf-8")

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
            if self._host_ok():
                self._login_page()
            return
        if path in ("/", "/index.html"):
            if self._guard(page=True):
                self._static("index.html")
            return
        if path.startswith("/static/"):
            # style.css is served to the login page too; everything else needs the token
            name = path[len("/static/") :]
            if (name == "style.css" and self._host_ok()) or self._guard():
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
        with suppress(OSError):  # keep the kernel's send queue short: a slow client drops frames
            self.connection.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 64 * 1024)
        self.send_response(HTTPStatus.OK)
        self.send_header("Content-Type", f"multipart/x-mixed-replace; boundary={BOUNDARY}")
        self.send_header("Cache-Control", "no-store")
        self.send_header("Connection", "close")
        self.send_header("X-Content-Type-Options", "nosniff")
        self.end_headers()
        self.close_connection = True
        stop = self.server.stop_event
        with slot.watch():
            seq = 0
            try:
                while not stop.is_set():
                    got = slot.wait_newer(seq, 0.5)
                    if got is None:
                        if self._client_gone():
                            return
                        continue
                    seq, jpeg = got
                    head = (f"--{BOUNDARY}\r\nContent-Type: image/jpeg\r\nContent-Length: {len(jpeg)}\r\n\r\n").encode(
                        "ascii"
                    )
                    self.wfile.write(head)
                    self.wfile.write(jpeg)
                    self.wfile.write(b"\r\n")
                    self.wfile.flush()
            except (OSError, ValueError):  # client went away (BrokenPipe, reset, timeout, closed file)
                return

    def _client_gone(self) -> bool:
        """True when the client closed its end (checked while no frame arrives, so idle streams end too)."""
        try:
            readable, _, _ = select.select([self.connection], [], [], 0)
            if not readable:
                return False
            return bool(self.connection.recv(1, socket.MSG_PEEK) == b"")
        except (OSError, ValueError):
            return True

    # -- POST ---------------------------------------------------------------------------------------
    def do_POST(self) -> None:
        """Login form and JSON commands."""
        path = urlsplit(self.path).path
        if not self._host_ok():
            self._error(HTTPStatus.MISDIRECTED_REQUEST, "unexpected Host header")
            return
        if not self._origin_ok():
            self._error(HTTPStatus.FORBIDDEN, "cross-origin request refused")
            return
        length = int(self.headers.get("Content-Length") or 0)
        if length > MAX_BODY:
            self._error(HTTPStatus.REQUEST_ENTITY_TOO_LARGE, "request body too large")
            return
        raw = self.rfile.read(length) if length > 0 else b""
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
        except (UnicodeDecodeError, json.JSONDecodeError) as err:
            self._error(HTTPStatus.BAD_REQUEST, f"invalid JSON: {err}")
            return
        if not isinstance(body, dict):
            self._error(HTTPStatus.BAD_REQUEST, "body must be a JSON object")
            return
        try:
            result = self.server.backend.command(path[len("/api/") :], body)
        except BadRequest as err:
            self._error(HTTPStatus.BAD_REQUEST, str(err))
            return
        self._json(result.status, result.body())

    def _login(self, raw: bytes) -> None:
        if self.server.token is None:
            self._send(HTTPStatus.SEE_OTHER, b"", "text/plain", {"Location": "/"})
            return
        form = parse_qs(raw.decode("utf-8", "replace"))
        presented = (form.get("token") or [""])[0]
        if not self.server.token_ok(presented):
            time.sleep(0.5)  # slow down guessing
            self._login_page("Wrong token.")
            return
        cookie = f"{COOKIE}={quote(presented, safe='')}; HttpOnly; SameSite=Strict; Path=/"
        self._send(HTTPStatus.SEE_OTHER, b"", "text/plain", {"Location": "/", "Set-Cookie": cookie})
