"""The web console's HTTP request handler (ROS-free): strict parsing, the guards, and the routes.

The routes, with who may reach each, are the table :data:`.api.ROUTES`; the streams are written by
:mod:`.relay`; the server this runs in, its lifecycle and the backend it calls are :mod:`.server`'s.

Guards: on a loopback bind only loopback ``Host`` names are answered (no DNS rebinding), elsewhere one sane
``Host``; with a token configured every request must carry it (``Authorization: Bearer``, ``X-Axis-Token`` or the
``axis_token`` cookie set by the login form), and wrong tokens are throttled per client network on every path
(:mod:`.auth`). POSTs must be ``application/json`` and same-origin (no cross-site request forgery from another
page in the operator's browser). Every malformed request gets a 4xx answer. The token is never logged, echoed or
put into a URL; the cookie is ``HttpOnly; SameSite=Strict`` (and ``Secure`` over HTTPS).
"""

from __future__ import annotations

import json
import math
import socket
import threading
from collections.abc import Callable
from contextlib import suppress
from html import escape as html_escape
from http import HTTPStatus
from http.cookies import SimpleCookie
from http.server import BaseHTTPRequestHandler
from pathlib import Path
from typing import Any, Protocol
from urllib.parse import parse_qs, quote, unquote, urlsplit

from axis_ptz_ros2.vapix.mjpeg import multipart_content_type
from axis_ptz_ros2.web.api import COMMANDS as COMMAND_FIELDS
from axis_ptz_ros2.web.api import STREAM_NAMES, BadRequest
from axis_ptz_ros2.web.auth import AuthThrottle
from axis_ptz_ros2.web.backend import ConsoleBackend
from axis_ptz_ros2.web.h264relay import CONTENT_TYPE as H264_CONTENT_TYPE
from axis_ptz_ros2.web.loopback import is_loopback
from axis_ptz_ros2.web.relay import BOUNDARY, FrameSlot, h264_parts, jpeg_parts, relay
from axis_ptz_ros2.web.tls import TlsIdentity

STATIC_TYPES = {
    ".html": "text/html; charset=utf-8",
    ".js": "text/javascript; charset=utf-8",
    ".css": "text/css; charset=utf-8",
    ".svg": "image/svg+xml",
    ".png": "image/png",
}
COOKIE = "axis_token"
MAX_BODY = 64 * 1024
STREAMS = STREAM_NAMES
COMMANDS = tuple(COMMAND_FIELDS)


class ConsoleHost(Protocol):
    """What a handler uses of the server it runs in (:class:`.server.ConsoleServer` is one)."""

    backend: ConsoleBackend
    bind: str
    io_timeout: float
    log: Callable[[str], None] | None
    static_dir: Path
    stop_event: threading.Event
    throttle: AuthThrottle
    tls: TlsIdentity | None
    token: str | None

    def token_ok(self, presented: str | None) -> bool:
        """Whether ``presented`` is the configured token (True when none is configured)."""
        ...


class ConsoleHandler(BaseHTTPRequestHandler):
    """One connection to the console: strict parsing, the guards, the routes of :data:`.api.ROUTES`."""

    server: ConsoleHost  # type: ignore[assignment]  # the stdlib declares its BaseServer
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
        elif path == "/video/still.jpg":
            self._still()
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

    def _still(self) -> None:
        """The last full-quality still as it came (404 until one has been taken: a still is not a stream)."""
        slot = self.server.backend.slot("still")
        seq, jpeg, _ = slot.latest() if slot is not None else (0, b"", 0.0)
        if seq == 0:
            self._error(HTTPStatus.NOT_FOUND, "no still has been taken yet")
            return
        self._send(HTTPStatus.OK, jpeg, "image/jpeg", {"X-Still-Seq": str(seq)})

    def _mjpeg(self, name: str) -> None:
        """multipart/x-mixed-replace stream of the newest frames until the client or the server goes."""
        slot = self._slot_or_404(name)
        if slot is None:
            return
        self._stream_head(multipart_content_type(BOUNDARY), sndbuf=64 * 1024)
        with slot.watch():
            relay(self.wfile, self.connection, self.server.stop_event, jpeg_parts(slot))

    def _h264(self, name: str) -> None:
        """The H.264 access units of a stream as length-prefixed records (:mod:`.h264relay`) until either side
        goes."""
        get = getattr(self.server.backend, "h264_slot", None)
        slot = get(name) if get is not None and name in STREAMS else None
        if slot is None:
            why = getattr(self.server.backend, "h264_refusal", None)
            reason = why(name) if why is not None and name in STREAMS else ""
            self._error(HTTPStatus.NOT_FOUND, f"no H.264 stream {name!r}" + (f": {reason}" if reason else ""))
            return
        self._stream_head(H264_CONTENT_TYPE, sndbuf=256 * 1024)
        with slot.watch() as client:
            relay(self.wfile, self.connection, self.server.stop_event, h264_parts(slot, client))

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
