"""The simulated camera's HTTP server (stdlib ``ThreadingHTTPServer``, HTTPS optional; ROS-free).

Endpoints and behaviour follow vapix.md §11 (the simulator contract): ``/axis-cgi/com/ptz.cgi`` (GET and POST
form), ``/axis-cgi/com/ptzconfig.cgi``, ``/axis-cgi/mjpg/video.cgi`` (+ ``/mjpg/video.mjpg``),
``/axis-cgi/jpg/image.cgi``, ``/axis-cgi/param.cgi`` (+ ``/axis-cgi/{admin,operator,view}/param.cgi``),
``/axis-cgi/imagesize.cgi`` and ``/axis-cgi/videostatus.cgi`` (+ ``/axis-cgi/view/…``); anything else gets the
real 404 page. Authentication: none, Basic, Digest (MD5, qop=auth) or both (§3). Test-only control endpoints
(never authenticated, never faulted): ``/sim/state`` (JSON ground truth) and ``/sim/control?…``
(:mod:`axis_ptz_ros2.sim.control`).

This module is the plumbing: :class:`HttpListener` (one of the camera's listeners), the request handler with
routing, auth, request faults (latency, HTTP errors, bandwidth cap), reboot behaviour; the endpoints themselves
are in :mod:`~axis_ptz_ros2.sim.http.vapix` and :mod:`~axis_ptz_ros2.sim.http.mjpeg`.
"""

from __future__ import annotations

import contextlib
import re
import socket
import ssl
import struct
import sys
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any
from urllib.parse import parse_qsl

from axis_ptz_ros2.sim import control
from axis_ptz_ros2.sim.http.mjpeg import serve_video
from axis_ptz_ros2.sim.http.pages import UNAUTHORIZED_HTML
from axis_ptz_ros2.sim.http.vapix import ENDPOINTS, HANDLERS, HTML, Reply, error_page, not_found
from axis_ptz_ros2.sim.view import CameraView


class _Server(ThreadingHTTPServer):
    daemon_threads = True
    block_on_close = False
    allow_reuse_address = True
    camera: CameraView
    tls: ssl.SSLContext | None = None
    conns: set[socket.socket]
    conns_lock: threading.Lock

    def process_request_thread(self, request: Any, client_address: Any) -> None:
        """With HTTPS, the TLS handshake runs here, on the connection's own thread (never the accept loop)."""
        if self.tls is not None:
            try:
                request.settimeout(10.0)
                request = self.tls.wrap_socket(request, server_side=True)
                request.settimeout(None)
            except (OSError, ssl.SSLError):
                self.shutdown_request(request)
                return
        super().process_request_thread(request, client_address)

    def handle_error(self, request: Any, client_address: Any) -> None:
        """A client that hangs up mid-stream is normal for a camera; anything else is printed."""
        exc = sys.exc_info()[1]
        if isinstance(exc, (ConnectionError, TimeoutError)):
            return
        super().handle_error(request, client_address)


class HttpListener:
    """The camera's VAPIX HTTP(S) server on ``host:port`` (port 0: any free one, kept across reopenings)."""

    def __init__(self, camera: CameraView, host: str, port: int) -> None:
        """Not listening yet: :meth:`open`."""
        self._camera = camera
        self._host = host
        self._port = port
        self._server: _Server | None = None
        self._thread: threading.Thread | None = None
        self._conns: set[socket.socket] = set()
        self._conns_lock = threading.Lock()

    @property
    def port(self) -> int:
        """The TCP port (the real one after binding port 0)."""
        return self._port

    def open(self) -> None:
        """Bind and serve in a thread (HTTPS when the camera has a TLS context)."""
        if self._server is not None:
            return
        server = _Server((self._host, self._port), CameraRequestHandler)
        server.camera = self._camera
        server.tls = self._camera.tls_context()
        server.conns, server.conns_lock = self._conns, self._conns_lock
        self._port = server.server_address[1]
        self._server = server
        self._thread = threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True)
        self._thread.start()

    def close(self, silently: bool = False) -> None:
        """Stop listening; close every connection (``silently``: leave them open and mute)."""
        server, self._server = self._server, None
        if server is not None:
            server.shutdown()
            server.server_close()
        with self._conns_lock:
            conns = [] if silently else list(self._conns)
        for c in conns:
            with contextlib.suppress(OSError):
                c.shutdown(socket.SHUT_RDWR)
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None


class CameraRequestHandler(BaseHTTPRequestHandler):
    """One HTTP connection to the simulated camera."""

    protocol_version = "HTTP/1.1"
    server_version = ""  # the persona decides (see version_string)
    sys_version = ""
    timeout = 60
    # Reply promptly like the camera's own stack: Nagle + delayed ACK would add ~40 ms to every query reply.
    disable_nagle_algorithm = True
    server: _Server

    # ---- plumbing -------------------------------------------------------------------------------------
    def setup(self) -> None:
        """Track the connection (a stop or reboot closes it)."""
        super().setup()
        with self.server.conns_lock:
            self.server.conns.add(self.connection)
        self._tokens_t = time.monotonic()

    def finish(self) -> None:
        """Forget the connection."""
        with self.server.conns_lock:
            self.server.conns.discard(self.connection)
        with contextlib.suppress(OSError):
            super().finish()

    def log_message(self, format: str, *args: Any) -> None:  # noqa: A002 - stdlib signature
        """Silent (and so never logs credentials)."""

    @property
    def cam(self) -> CameraView:
        """The camera this connection talks to."""
        return self.server.camera

    def version_string(self) -> str:
        """``Server:`` header of the persona ("" = none)."""
        return self.cam.persona.server_header

    def send_response(self, code: int, message: str | None = None) -> None:
        """Status line, ``Server`` only if the persona has one, ``Date``."""
        self.log_request(code)
        self.send_response_only(code, message)
        if self.cam.persona.server_header:
            self.send_header("Server", self.version_string())
        self.send_header("Date", self.date_time_string())

    def write(self, data: bytes) -> None:
        """Write honouring the bandwidth cap fault."""
        kbps = self.cam.faults.bandwidth_kbps
        if kbps <= 0:
            self.wfile.write(data)
            return
        rate = kbps * 1000.0 / 8.0  # bytes/s
        view = memoryview(data)
        chunk = max(256, int(rate / 50))
        for i in range(0, len(view), chunk):
            part = view[i : i + chunk]
            # Token bucket with a burst of one chunk.
            now = time.monotonic()
            allowed_at = self._tokens_t + len(part) / rate
            if allowed_at > now:
                time.sleep(allowed_at - now)
                self._tokens_t = allowed_at
            else:
                self._tokens_t = max(now - chunk / rate, self._tokens_t) + len(part) / rate
            self.wfile.write(part)

    def send(self, reply: Reply, extra: list[tuple[str, str]] | None = None) -> None:
        """Send ``reply`` (plus ``extra`` headers, which may repeat a name)."""
        data = reply.body.encode("utf-8") if isinstance(reply.body, str) else reply.body
        self.send_response(reply.status)
        if reply.status != 204:
            self.send_header("Content-Type", reply.ctype)
            self.send_header("Content-Length", str(len(data)))
        for k, v in reply.headers.items():
            self.send_header(k, v)
        for k, v in extra or []:
            self.send_header(k, v)
        self.end_headers()
        if reply.status != 204 and self.command != "HEAD":
            self.write(data)
        self.cam.requests.count("", reply.status)

    def unauthorized(self, path: str, stale: bool = False) -> None:
        """401 with the camera's challenges (the page's form depends on the challenge style)."""
        challenges = [("WWW-Authenticate", c) for c in self.cam.challenges(stale)]
        if self.cam.challenge_style == "legacy":
            self.send(Reply(401, b"", "text/html"), challenges)
            return
        self.send(Reply(401, UNAUTHORIZED_HTML.format(path=path), HTML), challenges)

    def hold_silently(self) -> None:
        """A request that arrived while the camera drops packets: never answered; when the camera is back
        the connection is reset (the rebooted camera knows nothing of it)."""
        cam = self.cam
        while cam.blackholed and not cam.stopping.is_set():
            cam.stopping.wait(0.05)
        self._abort_connection()

    def _abort_connection(self) -> None:
        """Close with a reset (no FIN first): the socket closes for real once the handler's files are closed,
        before the server's own ``shutdown(SHUT_WR)`` could send a FIN."""
        self.close_connection = True
        with contextlib.suppress(OSError):
            self.connection.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
            self.connection.close()

    # ---- dispatch -------------------------------------------------------------------------------------
    def do_GET(self) -> None:  # noqa: N802 - stdlib name
        """A request with its arguments in the query string."""
        self._dispatch("")

    def do_POST(self) -> None:  # noqa: N802 - stdlib name
        """A request with (more) arguments in a form body."""
        n = int(self.headers.get("Content-Length") or 0)
        body = self.rfile.read(n).decode("utf-8", "replace") if n > 0 else ""
        self._dispatch(body)

    def _reboot_error(self, path: str) -> None:
        kind = self.cam.reboot_error_kind
        if kind == "empty":
            self.close_connection = True  # connection accepted, then closed (FIN) without a byte of reply
        elif kind == "401":
            self.unauthorized(path)
        else:
            self.send(error_page(503))

    def _raw_target(self) -> str:
        """The request target exactly as on the request line (the stdlib rewrites a leading "//" in
        ``self.path``; Digest clients sign the target they sent)."""
        parts = self.requestline.split()
        return parts[1] if len(parts) >= 2 else self.path

    def _sim(self, path: str, args: list[tuple[str, str]]) -> None:
        got = control.handle(self.cam, path, args)
        if got.status == 404:
            self.send(not_found(path))
            return
        self.send(Reply(got.status, got.body, "application/json"))
        if got.reboot_s is not None:
            self.close_connection = True
            self.wfile.flush()
            got.start_reboot(self.cam)

    def _dispatch(self, body: str) -> None:
        cam = self.cam
        # Route on the path with repeated slashes collapsed ("//axis-cgi/…" is sloppy but valid and a released
        # ROS driver sends it); authenticate against the raw request target, which is what the client signed.
        raw_target = self._raw_target()
        target = raw_target.partition("#")[0]
        raw_path, _, raw_query = target.partition("?")
        path = re.sub(r"/{2,}", "/", raw_path)
        query = raw_query + ("&" if raw_query and body else "") + body
        try:
            args = parse_qsl(query, keep_blank_values=True, strict_parsing=False)
        except ValueError:
            args = []
        if cam.blackholed:
            self.hold_silently()
            return
        if path.startswith("/sim/"):
            self._sim(path, args)
            return
        endpoint = ENDPOINTS.get(path, "")
        if cam.serving_errors() and endpoint:
            cam.requests.count(endpoint)
            self._reboot_error(path)
            return
        cam.requests.count(endpoint or "other")
        is_video = endpoint in ("video", "image")
        if is_video:  # what the camera was asked for (tests: "the camera never saw it")
            cam.requests.log_video(self.command, query)
        faults = cam.faults
        if faults.latency_ms > 0:
            time.sleep(faults.latency_ms / 1000.0)
        if faults.http_error and endpoint and (faults.http_error_scope == "all" or is_video):
            if faults.http_error == 401:
                self.unauthorized(path)
            else:
                self.send(error_page(faults.http_error))
            return
        authorization = self.headers.get("Authorization")
        cam.requests.count_auth(authorization)
        verdict = cam.auth_result(authorization, self.command, raw_target)
        if verdict != "ok":
            self.unauthorized(path, stale=verdict == "stale")
            return
        if endpoint == "video":
            serve_video(self, args)
            return
        handler = HANDLERS.get(endpoint)
        if handler is None:
            self.send(not_found(path))
            return
        self.send(handler(cam, self.command, args, query))
