"""A faithful simulated Axis 214 PTZ network camera over HTTP (stdlib ``ThreadingHTTPServer``, ROS-free).

Endpoints and behaviour follow vapix.md §11 (the simulator contract): ``/axis-cgi/com/ptz.cgi`` (GET and POST
form), ``/axis-cgi/com/ptzconfig.cgi``, ``/axis-cgi/mjpg/video.cgi`` (+ ``/mjpg/video.mjpg``),
``/axis-cgi/jpg/image.cgi``, ``/axis-cgi/param.cgi`` (+ ``/axis-cgi/{admin,operator,view}/param.cgi``),
``/axis-cgi/imagesize.cgi`` and ``/axis-cgi/videostatus.cgi`` (+ ``/axis-cgi/view/…``); anything else gets the
real 404 page. Authentication: none, Basic, Digest (MD5, qop=auth) or both (§3). Test-only control endpoints
(never authenticated, never faulted): ``/sim/state`` (JSON ground truth) and ``/sim/control?…`` (faults,
reboot, teleport, counter reset).

Every JPEG carries a COM segment right after SOI: ``axsim seq=<n> t=<time.time_ns() at send>``.
"""

from __future__ import annotations

import base64
import collections
import contextlib
import copy
import dataclasses
import hashlib
import hmac
import json
import os
import re
import secrets
import socket
import ssl
import struct
import sys
import threading
import time
from dataclasses import dataclass, field
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from types import TracebackType
from typing import Any
from urllib.parse import parse_qsl

import cv2
import numpy as np

from axis_ptz_ros2.sim.faults import FaultConfig
from axis_ptz_ros2.sim.persona import (
    ERROR_HTML,
    NOT_FOUND_HTML,
    READ_ONLY_PREFIXES,
    UNAUTHORIZED_HTML,
    Persona,
    list_params,
    persona,
    preset_params,
)
from axis_ptz_ros2.sim.ptz import PtzCommandError, PtzState, Speeds
from axis_ptz_ros2.sim.renderer import PtzRenderer, encode_jpeg, insert_comment
from axis_ptz_ros2.sim.scene import PtzLimits, SimWorld, load_world
from axis_ptz_ros2.sim.tls import SelfSignedCertificate

AUTH_MODES = ("none", "basic", "digest", "basic_digest")
BOUNDARY = "myboundary"
MAX_FPS = 30
NONCE_LIFETIME_S = 600.0  #: default Digest nonce lifetime (a guess: real Axis lifetimes are not documented)
CHALLENGE_STYLES = ("current", "legacy")
REBOOT_ERROR_KINDS = ("503", "empty", "401")

_VIDEO_PATHS = ("/axis-cgi/mjpg/video.cgi", "/mjpg/video.mjpg")
_ENDPOINTS: dict[str, str] = {
    "/axis-cgi/com/ptz.cgi": "ptz",
    "/axis-cgi/com/ptzconfig.cgi": "ptzconfig",
    "/axis-cgi/mjpg/video.cgi": "video",
    "/mjpg/video.mjpg": "video",
    "/axis-cgi/jpg/image.cgi": "image",
    "/axis-cgi/param.cgi": "param",
    "/axis-cgi/admin/param.cgi": "param",
    "/axis-cgi/operator/param.cgi": "param",
    "/axis-cgi/view/param.cgi": "param",
    "/axis-cgi/imagesize.cgi": "imagesize",
    "/axis-cgi/view/imagesize.cgi": "imagesize",
    "/axis-cgi/videostatus.cgi": "videostatus",
    "/axis-cgi/view/videostatus.cgi": "videostatus",
}
_PTZ_CONTROL_KEYS = ("pan", "tilt", "zoom", "rpan", "rtilt", "rzoom", "move", "center", "areazoom")


@dataclass
class PtzLogEntry:
    """One received ``ptz.cgi`` request."""

    t_wall: float
    t_mono: float
    method: str
    query: str


@dataclass
class RequestCounts:
    """Requests seen by the simulator: per endpoint, per PTZ command kind, and a log of PTZ queries."""

    endpoints: collections.Counter[str] = field(default_factory=collections.Counter)
    ptz: collections.Counter[str] = field(default_factory=collections.Counter)
    ptz_log: list[PtzLogEntry] = field(default_factory=list)
    video_log: list[PtzLogEntry] = field(default_factory=list)  #: video.cgi / image.cgi requests (query strings)
    status: collections.Counter[int] = field(default_factory=collections.Counter)
    auth: collections.Counter[str] = field(default_factory=collections.Counter)  #: Authorization scheme seen

    def as_dict(self) -> dict[str, Any]:
        """JSON-friendly mapping."""
        return {
            "endpoints": dict(self.endpoints),
            "ptz": dict(self.ptz),
            "status": {str(k): v for k, v in self.status.items()},
            "auth": dict(self.auth),
            "ptz_log": [[e.t_wall, e.method, e.query] for e in self.ptz_log[-200:]],
            "video_log": [[e.t_wall, e.method, e.query] for e in self.video_log[-200:]],
        }


class _Server(ThreadingHTTPServer):
    daemon_threads = True
    block_on_close = False
    allow_reuse_address = True
    camera: SimulatedCamera
    tls: ssl.SSLContext | None = None

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


class SimulatedCamera:
    """A simulated Axis PTZ camera: ``start()`` it, talk VAPIX to ``base_url``, ``stop()`` it.

    ``model`` picks the persona (:mod:`axis_ptz_ros2.sim.persona`): ``axis214`` (default) or ``q6075``.
    ``auth`` is one of ``none`` (anonymous, the thesis' set-up), ``basic``, ``digest``, ``basic_digest``;
    None = the persona's default (214: none; q6075: digest). ``https`` None = the persona's default (214: off;
    q6075: on, with a self-signed certificate generated at start-up whose path is :attr:`ca_file`).
    The password is never logged or shown in reprs.
    """

    def __init__(
        self,
        world: SimWorld | None = None,
        host: str = "127.0.0.1",
        port: int = 0,
        auth: str | None = None,
        user: str = "root",
        password: str = "pass",
        faults: FaultConfig | None = None,
        speeds: Speeds | None = None,
        mac: str = "00408C1A2B3C",
        default_fps: int = MAX_FPS,
        nonce_lifetime_s: float = NONCE_LIFETIME_S,
        challenge_style: str = "current",
        model: str | Persona | None = None,
        https: bool | None = None,
    ) -> None:
        self.persona = persona(model)
        auth = self.persona.default_auth if auth is None else auth
        if auth not in AUTH_MODES:
            raise ValueError(f"auth must be one of {AUTH_MODES}")
        self.set_auth_options(nonce_lifetime_s=nonce_lifetime_s, challenge_style=challenge_style)
        if not re.fullmatch(r"[0-9A-Fa-f]{12}", mac):
            raise ValueError("mac must be 12 hex digits")
        world = world if world is not None else load_world()
        if self.persona.limits is not None or self.persona.zoom_model is not None:
            world = dataclasses.replace(
                world,
                limits=self.persona.limits or world.limits,
                zoom_model=self.persona.zoom_model or world.zoom_model,
                kinematics=self.persona.kinematics or world.kinematics,
            )
        self.world = world
        self.https = self.persona.https if https is None else https
        self._cert: SelfSignedCertificate | None = None
        self.host = host
        self._port = port
        self.auth = auth
        self.user = user
        self._password = password
        self.mac = mac.upper()
        self.realm = f"AXIS_{self.mac}"
        self.default_fps = default_fps
        self.faults = faults if faults is not None else FaultConfig()
        self.state = PtzState(
            limits=self.world.limits,
            zoom_model=self.world.zoom_model,
            speeds=speeds or self.persona.speeds,
            default_image_size=self.persona.resolutions[self.persona.default_resolution],
            move_step_fov=self.persona.move_step_fov,
            attributes=self.persona.attributes,
            whoami=self.persona.whoami,
        )
        self.params = self.persona.parameter_tree(self.world.limits, self.world.zoom_model, self.mac, auth)
        if self.persona.key != "axis214":
            self.params["HTTPS.Enabled"] = "yes" if self.https else "no"
        self._renderer: PtzRenderer | None = None
        self._counts = RequestCounts()
        self._counts_lock = threading.Lock()
        self._nonces: dict[str, float] = {}
        self._nonce_lock = threading.Lock()
        self._server: _Server | None = None
        self._thread: threading.Thread | None = None
        self._conns: set[socket.socket] = set()
        self._conns_lock = threading.Lock()
        self._stopping = threading.Event()
        self._rebooting = threading.Event()
        self._reboot_gen = 0
        self._blackholed = threading.Event()  #: a reboot that drops packets: connects hang, requests vanish
        self._blackhole_socks: list[socket.socket] = []
        self._errors_until = 0.0  #: monotonic end of the "web server up, video not yet" phase of a reboot
        self._error_kind = "503"
        self.video_ok_at: float | None = None  #: wall time (time.time()) video was served again after a reboot
        self._lifecycle = threading.Lock()
        self._jpeg_cache: collections.OrderedDict[tuple[Any, ...], bytes] = collections.OrderedDict()
        self._jpeg_lock = threading.Lock()
        self.frames_sent = 0
        self.snapshots_sent = 0

    def __repr__(self) -> str:
        url = self.base_url if self._port else None
        return f"SimulatedCamera(model={self.persona.key!r}, url={url!r}, auth={self.auth!r}, user={self.user!r})"

    # ---- lifecycle ------------------------------------------------------------------------------------
    @property
    def renderer(self) -> PtzRenderer:
        """The view renderer (built on first use: the scene takes a moment)."""
        if self._renderer is None:
            self._renderer = PtzRenderer(self.world)
        return self._renderer

    def start(self) -> SimulatedCamera:
        """Build the scene and start serving (returns self)."""
        _ = self.renderer
        self._stopping.clear()
        self.forget_nonces()
        self._listen()
        return self

    def _listen(self) -> None:
        server = _Server((self.host, self._port), _Handler)
        server.camera = self
        if self.https:
            if self._cert is None:
                self._cert = SelfSignedCertificate.generate(self.host, self.mac)
            server.tls = self._cert.server_context()
        self._port = server.server_address[1]
        self._server = server
        self._thread = threading.Thread(
            target=server.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True
        )
        self._thread.start()

    def _close_all(self, silently: bool = False) -> None:
        """Stop listening; close every connection (``silently``: leave them open and mute, as a camera that
        lost power does: its peers notice only through their own timeouts)."""
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

    def stop(self) -> None:
        """Stop serving and close every connection (fast); removes the generated certificate."""
        with self._lifecycle:
            self._stopping.set()
            self._reboot_gen += 1
            self._rebooting.clear()
            self._close_all()
            self._end_blackhole()
            if self._cert is not None:
                self._cert.cleanup()
                self._cert = None

    def __enter__(self) -> SimulatedCamera:
        return self.start()

    def __exit__(
        self, et: type[BaseException] | None, ev: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.stop()

    @property
    def port(self) -> int:
        """The TCP port (the real one after binding port 0)."""
        return self._port

    @property
    def base_url(self) -> str:
        """``http://host:port`` (``https://`` when serving HTTPS)."""
        return f"{'https' if self.https else 'http'}://{self.host}:{self._port}"

    @property
    def ca_file(self) -> str | None:
        """PEM file of the self-signed certificate served over HTTPS (a client's CA bundle), else None."""
        return str(self._cert.cert_file) if self._cert is not None else None

    def current_params(self) -> dict[str, str]:
        """The parameter tree as listed now (a modern camera's presets appear under ``PTZ.Preset.P0``)."""
        if not self.persona.preset_params:
            return self.params
        presets = [(p.number, p.name, p.pan, p.tilt, p.zoom) for p in self.state.presets_snapshot()]
        tree = dict(self.params)
        tree.update(preset_params(presets, self.state.home))
        return tree

    @property
    def rebooting(self) -> bool:
        """Whether a simulated reboot is in progress."""
        return self._rebooting.is_set()

    def reboot(
        self, seconds: float, *, blackhole: bool = False, errors_s: float = 0.0, error_kind: str = "503"
    ) -> None:
        """Simulate a reboot (returns immediately), then come back on the same port at the home position with
        every Digest nonce forgotten.

        For ``seconds`` the camera is gone: connections are refused at once (``blackhole=False``, what the
        loopback interface does when nothing listens), or packets are dropped (``blackhole=True``, what a
        rebooting camera on a real network does: a connect hangs until the client's timeout, open
        connections go silent and requests on them are never answered). Then for ``errors_s`` its web server
        answers every camera request with ``error_kind`` (``503``, ``empty``: connection closed without a
        reply, or ``401``) before video works; :attr:`video_ok_at` records when it does (wall time).
        """
        if error_kind not in REBOOT_ERROR_KINDS:
            raise ValueError(f"error_kind must be one of {REBOOT_ERROR_KINDS}")
        if seconds < 0 or errors_s < 0:
            raise ValueError("reboot durations must be >= 0")
        with self._lifecycle:
            if self._server is None:
                raise RuntimeError("camera not running")
            if blackhole:
                self._blackholed.set()  # before the generation changes: streams must go mute, not close
            self._rebooting.set()
            self._reboot_gen += 1
            gen = self._reboot_gen
            self.video_ok_at = None
            self._close_all(silently=blackhole)
            if blackhole:
                self._start_blackhole()

        def come_back() -> None:
            deadline = time.monotonic() + seconds
            while time.monotonic() < deadline:
                if self._stopping.wait(min(0.05, max(0.0, deadline - time.monotonic()))):
                    return
            with self._lifecycle:
                if gen != self._reboot_gen or self._stopping.is_set():
                    return
                self._end_blackhole()
                self.state.reset()
                self.forget_nonces()
                self._error_kind = error_kind
                self._errors_until = time.monotonic() + errors_s
                for _ in range(100):
                    try:
                        self._listen()
                        break
                    except OSError:
                        time.sleep(0.05)
                self.video_ok_at = time.time() + errors_s
            if self._stopping.wait(errors_s):
                return
            if gen == self._reboot_gen:
                self._rebooting.clear()

        threading.Thread(target=come_back, daemon=True).start()

    def serving_errors(self) -> bool:
        """Whether the camera is in the "web server up, video not yet" phase of a reboot."""
        return time.monotonic() < self._errors_until

    def _start_blackhole(self) -> None:
        """Hold the port with a listener that never accepts and whose (tiny) accept queue is full: the kernel
        then drops every new SYN, so a client's connect hangs as if the camera were off the network."""
        family = socket.AF_INET6 if ":" in self.host else socket.AF_INET
        listener = socket.socket(family, socket.SOCK_STREAM)
        listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        for _ in range(100):
            try:
                listener.bind((self.host, self._port))
                break
            except OSError:
                time.sleep(0.02)
        listener.listen(0)
        socks = [listener]
        for _ in range(4):
            filler = socket.socket(family, socket.SOCK_STREAM)
            filler.setblocking(False)
            filler.connect_ex((self.host, self._port))
            socks.append(filler)
        self._blackhole_socks = socks

    def _end_blackhole(self) -> None:
        socks, self._blackhole_socks = self._blackhole_socks, []
        for sock in socks:
            with contextlib.suppress(OSError):
                sock.close()
        self._blackholed.clear()  # held requests now end with a reset, as for a peer that rebooted


    # ---- ground truth and control ----------------------------------------------------------------------
    def position(self) -> tuple[float, float, float]:
        """True current VAPIX (pan°, tilt°, zoom units), intermediate while moving."""
        return self.state.position()

    def teleport(self, pan: float, tilt: float, zoom: float) -> None:
        """Put the head at a pose instantly (test helper; clamped to the limits, stops all motion)."""
        self.state.handle([("pan", str(pan)), ("tilt", str(tilt)), ("zoom", str(int(zoom)))])
        with self.state._lock:  # noqa: SLF001 - same package
            self.state._pan.pos = (
                self.state._pan.target if self.state._pan.target is not None else self.state._pan.pos
            )
            self.state._tilt.pos = (
                self.state._tilt.target if self.state._tilt.target is not None else self.state._tilt.pos
            )
            self.state._zoom.pos = (
                self.state._zoom.target if self.state._zoom.target is not None else self.state._zoom.pos
            )
            self.state._pan.target = self.state._tilt.target = self.state._zoom.target = None

    @property
    def request_counts(self) -> RequestCounts:
        """A snapshot copy of the request counters and the PTZ request log."""
        with self._counts_lock:
            return copy.deepcopy(self._counts)

    def reset_counts(self) -> None:
        """Clear the request counters and log."""
        with self._counts_lock:
            self._counts = RequestCounts()

    def set_faults(self, faults: FaultConfig | None = None, **changes: Any) -> FaultConfig:
        """Replace the fault configuration (``faults``) and/or change single faults; returns the new one."""
        base = faults if faults is not None else self.faults
        self.faults = base.replace(**changes) if changes else base
        return self.faults

    def state_dict(self) -> dict[str, Any]:
        """Ground truth for ``/sim/state``."""
        pan, tilt, zoom = self.position()
        with self._counts_lock:
            counts = self._counts.as_dict()
        return {
            "pan": pan,
            "tilt": tilt,
            "zoom": zoom,
            "moving": self.state.moving(),
            "speed": self.state.speed,
            "faults": self.faults.as_dict(),
            "rebooting": self.rebooting,
            "blackholed": self._blackholed.is_set(),
            "serving_errors": self.serving_errors(),
            "video_ok_at": self.video_ok_at,
            "nonce_lifetime_s": self.nonce_lifetime_s,
            "challenge_style": self.challenge_style,
            "frames_sent": self.frames_sent,
            "snapshots_sent": self.snapshots_sent,
            "renders": self.renderer.renders,
            "counts": counts,
        }

    # ---- auth ------------------------------------------------------------------------------------------
    def set_auth_options(self, *, nonce_lifetime_s: float | None = None, challenge_style: str | None = None) -> None:
        """Digest nonce lifetime (seconds, > 0) and the 401 form: ``current`` (``algorithm=MD5, qop="auth"``,
        HTML body, ``stale=true`` only for an expired nonce) or ``legacy`` (older firmware: empty body,
        ``stale=FALSE`` or ``stale=TRUE`` always present, ``qop="auth"``, no ``algorithm``)."""
        if nonce_lifetime_s is not None:
            if not nonce_lifetime_s > 0:
                raise ValueError("nonce_lifetime_s must be > 0")
            self.nonce_lifetime_s = float(nonce_lifetime_s)
        if challenge_style is not None:
            if challenge_style not in CHALLENGE_STYLES:
                raise ValueError(f"challenge_style must be one of {CHALLENGE_STYLES}")
            self.challenge_style = challenge_style

    def forget_nonces(self) -> None:
        """What a restart does: every nonce handed out so far becomes unknown."""
        with self._nonce_lock:
            self._nonces.clear()

    def _new_nonce(self) -> str:
        nonce = (
            base64.b64encode(secrets.token_bytes(12)).decode()
            + hashlib.sha1(secrets.token_bytes(8)).hexdigest()
        )
        now = time.monotonic()
        with self._nonce_lock:
            if len(self._nonces) > 2000:
                for k in [k for k, t in self._nonces.items() if now - t > self.nonce_lifetime_s]:
                    del self._nonces[k]
            self._nonces[nonce] = now
        return nonce

    def challenges(self, stale: bool = False) -> list[str]:
        """``WWW-Authenticate`` values for the current auth mode (``stale``: the nonce sent had expired)."""
        out = []
        if self.auth in ("digest", "basic_digest"):
            nonce = self._new_nonce()
            if self.challenge_style == "legacy":
                flag = "TRUE" if stale else "FALSE"
                out.append(f'Digest realm="{self.realm}", nonce="{nonce}", stale={flag}, qop="auth"')
            else:
                tail = ", stale=true" if stale else ""
                out.append(f'Digest realm="{self.realm}", nonce="{nonce}", algorithm=MD5, qop="auth"{tail}')
        if self.auth in ("basic", "basic_digest"):
            out.append(f'Basic realm="{self.realm}"')
        return out

    def check_auth(self, header: str | None, method: str, uri: str) -> bool:
        """Whether an ``Authorization`` header is valid for this request (``uri``: the raw request target)."""
        return self.auth_result(header, method, uri) == "ok"

    def auth_result(self, header: str | None, method: str, uri: str) -> str:
        """``ok``, ``stale`` (a correct Digest response to an expired nonce) or ``fail``."""
        if self.auth == "none":
            return "ok"
        if not header:
            return "fail"
        scheme, _, rest = header.partition(" ")
        scheme = scheme.lower()
        if scheme == "basic" and self.auth in ("basic", "basic_digest"):
            try:
                user, _, pw = base64.b64decode(rest.strip(), validate=True).decode("utf-8").partition(":")
            except (ValueError, UnicodeDecodeError):
                return "fail"
            good = hmac.compare_digest(user, self.user) and hmac.compare_digest(pw.encode(), self._password.encode())
            return "ok" if good else "fail"
        if scheme == "digest" and self.auth in ("digest", "basic_digest"):
            f = {
                m.group(1).lower(): m.group(3) if m.group(3) is not None else m.group(4)
                for m in _DIGEST_FIELD.finditer(rest)
            }
            nonce = f.get("nonce", "")
            # The signed uri must be the request target as sent (e.g. "//axis-cgi/com/ptz.cgi?…"), not a
            # normalised path: that is what the client hashed.
            if f.get("username") != self.user or f.get("realm") != self.realm or f.get("uri") != uri:
                return "fail"
            algorithm = (f.get("algorithm") or "MD5").upper()
            if algorithm != "MD5":
                return "fail"
            ha1 = _md5(f"{self.user}:{self.realm}:{self._password}")
            ha2 = _md5(f"{method}:{uri}")
            qop = f.get("qop")
            if qop == "auth":
                expected = _md5(f"{ha1}:{nonce}:{f.get('nc', '')}:{f.get('cnonce', '')}:auth:{ha2}")
            elif qop is None:
                expected = _md5(f"{ha1}:{nonce}:{ha2}")
            else:
                return "fail"
            if not hmac.compare_digest(expected, f.get("response", "").lower()):
                return "fail"
            with self._nonce_lock:
                issued = self._nonces.get(nonce)
            if issued is None:
                return "fail"  # never issued, or forgotten by a restart
            if time.monotonic() - issued > self.nonce_lifetime_s:
                return "stale"
            return "ok"
        return "fail"

    # ---- frames ----------------------------------------------------------------------------------------
    def frame_jpeg(self, width: int, height: int, compression: int, overlay: str = "") -> bytes:
        """The current view as JPEG (cached per view, quality and overlay text)."""
        pan, tilt, zoom = self.position()
        key = (round(pan, 5), round(tilt, 5), round(zoom, 3), width, height, compression, overlay)
        with self._jpeg_lock:
            jpeg = self._jpeg_cache.get(key)
        if jpeg is not None:
            return jpeg
        img = self.renderer.render(pan, tilt, zoom, width, height)
        if overlay:
            img = np.array(img)
            scale = max(0.35, width / 1400.0)
            (tw, th), _ = cv2.getTextSize(overlay, cv2.FONT_HERSHEY_SIMPLEX, scale, 1)
            cv2.rectangle(img, (2, 2), (8 + tw, 8 + th + 2), (0, 0, 0), -1)
            cv2.putText(
                img, overlay, (5, 5 + th), cv2.FONT_HERSHEY_SIMPLEX, scale, (255, 255, 255), 1, cv2.LINE_AA
            )
        jpeg = encode_jpeg(img, compression)
        with self._jpeg_lock:
            self._jpeg_cache[key] = jpeg
            while len(self._jpeg_cache) > 16:
                self._jpeg_cache.popitem(last=False)
        return jpeg

    def _count(self, endpoint: str, status: int | None = None) -> None:
        with self._counts_lock:
            if endpoint:
                self._counts.endpoints[endpoint] += 1
            if status is not None:
                self._counts.status[status] += 1

    def _log_ptz(self, method: str, query: str, args: list[tuple[str, str]]) -> None:
        with self._counts_lock:
            self._counts.ptz_log.append(PtzLogEntry(time.time(), time.monotonic(), method, query))
            if len(self._counts.ptz_log) > 100000:
                del self._counts.ptz_log[:50000]
            for k, v in args:
                kl = k.lower()
                self._counts.ptz[f"{kl}={v}" if kl in ("query", "move") else kl] += 1


_DIGEST_FIELD = re.compile(r'(\w+)=("([^"]*)"|([^,\s]*))')


def _md5(s: str) -> str:
    return hashlib.md5(s.encode("utf-8")).hexdigest()  # noqa: S324 - HTTP Digest is MD5 by definition


class _StreamClosedError(Exception):
    """The MJPEG connection ended (client gone, camera stopped, or a drop fault)."""


class _Handler(BaseHTTPRequestHandler):
    protocol_version = "HTTP/1.1"
    server_version = ""  # the persona decides (see version_string)
    sys_version = ""
    timeout = 60
    # Reply promptly like the camera's own stack: Nagle + delayed ACK would add ~40 ms to every query reply.
    disable_nagle_algorithm = True
    server: _Server

    # ---- plumbing -------------------------------------------------------------------------------------
    def setup(self) -> None:
        super().setup()
        cam = self.server.camera
        with cam._conns_lock:
            cam._conns.add(self.connection)
        self._tokens_t = time.monotonic()
        self._sent_bytes = 0.0

    def finish(self) -> None:
        cam = self.server.camera
        with cam._conns_lock:
            cam._conns.discard(self.connection)
        with contextlib.suppress(OSError):
            super().finish()

    def log_message(self, format: str, *args: Any) -> None:  # noqa: A002 - stdlib signature
        """Silent (and so never logs credentials)."""


    @property
    def cam(self) -> SimulatedCamera:
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

    def _write(self, data: bytes) -> None:
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

    def _reply(
        self,
        status: int,
        body: bytes | str = b"",
        ctype: str = "text/plain",
        headers: dict[str, str] | None = None,
        extra: list[tuple[str, str]] | None = None,
    ) -> None:
        data = body.encode("utf-8") if isinstance(body, str) else body
        self.send_response(status)
        if status != 204:
            self.send_header("Content-Type", ctype)
            self.send_header("Content-Length", str(len(data)))
        for k, v in (headers or {}).items():
            self.send_header(k, v)
        for k, v in extra or []:
            self.send_header(k, v)
        self.end_headers()
        if status != 204 and self.command != "HEAD":
            self._write(data)
        self.cam._count("", status)

    def _unauthorized(self, path: str, stale: bool = False) -> None:
        challenges = [("WWW-Authenticate", c) for c in self.cam.challenges(stale)]
        if self.cam.challenge_style == "legacy":
            self._reply(401, b"", "text/html", extra=challenges)
            return
        self._reply(401, UNAUTHORIZED_HTML.format(path=path), "text/html; charset=ISO-8859-1", extra=challenges)

    # ---- dispatch -------------------------------------------------------------------------------------
    def do_GET(self) -> None:  # noqa: N802 - stdlib name
        self._dispatch("")

    def do_POST(self) -> None:  # noqa: N802 - stdlib name
        n = int(self.headers.get("Content-Length") or 0)
        body = self.rfile.read(n).decode("utf-8", "replace") if n > 0 else ""
        self._dispatch(body)

    def _hold_silently(self) -> None:
        """A request that arrived while the camera drops packets: never answered; when the camera is back
        the connection is reset (the rebooted camera knows nothing of it)."""
        cam = self.cam
        while cam._blackholed.is_set() and not cam._stopping.is_set():
            cam._stopping.wait(0.05)
        self._abort_connection()

    def _abort_connection(self) -> None:
        """Close with a reset (no FIN first): the socket closes for real once the handler's files are closed,
        before the server's own ``shutdown(SHUT_WR)`` could send a FIN."""
        self.close_connection = True
        with contextlib.suppress(OSError):
            self.connection.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
            self.connection.close()

    def _reboot_error(self, path: str) -> None:
        kind = self.cam._error_kind
        if kind == "empty":
            self.close_connection = True  # connection accepted, then closed (FIN) without a byte of reply
        elif kind == "401":
            self._unauthorized(path)
        else:
            self._reply(
                503, ERROR_HTML.format(code=503, reason="Service Unavailable"), "text/html; charset=ISO-8859-1"
            )

    def _raw_target(self) -> str:
        """The request target exactly as on the request line (the stdlib rewrites a leading "//" in
        ``self.path``; Digest clients sign the target they sent)."""
        parts = self.requestline.split()
        return parts[1] if len(parts) >= 2 else self.path

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
        if cam._blackholed.is_set():
            self._hold_silently()
            return
        if path.startswith("/sim/"):
            self._sim(path, args)
            return
        if cam.serving_errors() and _ENDPOINTS.get(path):
            cam._count(_ENDPOINTS[path])
            self._reboot_error(path)
            return
        endpoint = _ENDPOINTS.get(path, "")
        cam._count(endpoint or "other")
        if endpoint in ("video", "image"):  # what the camera was asked for (tests: "the camera never saw it")
            with cam._counts_lock:
                cam._counts.video_log.append(PtzLogEntry(time.time(), time.monotonic(), self.command, query))
                del cam._counts.video_log[:-10000]
        faults = cam.faults
        if faults.latency_ms > 0:
            time.sleep(faults.latency_ms / 1000.0)
        is_video = endpoint in ("video", "image")
        if faults.http_error and endpoint and (faults.http_error_scope == "all" or is_video):
            if faults.http_error == 401:
                self._unauthorized(path)
            else:
                code = faults.http_error
                reason = {500: "Internal Server Error", 503: "Service Unavailable"}[code]
                self._reply(
                    code, ERROR_HTML.format(code=code, reason=reason), "text/html; charset=ISO-8859-1"
                )
            return
        authorization = self.headers.get("Authorization")
        with cam._counts_lock:
            cam._counts.auth[authorization.split(" ", 1)[0].lower() if authorization else "none"] += 1
        verdict = cam.auth_result(authorization, self.command, raw_target)
        if verdict != "ok":
            self._unauthorized(path, stale=verdict == "stale")
            return
        handler = {
            "ptz": self._ptz,
            "ptzconfig": self._ptzconfig,
            "video": self._video,
            "image": self._image,
            "param": self._param,
            "imagesize": self._imagesize,
            "videostatus": self._videostatus,
        }.get(endpoint)
        if handler is None:
            self._reply(404, NOT_FOUND_HTML.format(path=path), "text/html; charset=ISO-8859-1")
            return
        handler(args, query)

    # ---- PTZ ------------------------------------------------------------------------------------------
    def _ptz(self, args: list[tuple[str, str]], query: str) -> None:
        self.cam._log_ptz(self.command, query, args)
        try:
            reply = self.cam.state.handle(args)
        except PtzCommandError as err:
            self._reply(200, f"Error:\n{err}\n")
            return
        if reply is None:
            self._reply(204)
        else:
            self._reply(200, reply)

    def _ptzconfig(self, args: list[tuple[str, str]], query: str) -> None:
        self.cam._log_ptz(self.command, query, args)
        try:
            self.cam.state.handle_config(args)
        except PtzCommandError as err:
            self._reply(200, f"Error:\n{err}\n")
            return
        self._reply(204)

    # ---- parameters -----------------------------------------------------------------------------------
    def _param(self, args: list[tuple[str, str]], query: str) -> None:
        cam = self.cam
        action = next((v for k, v in args if k == "action"), "")
        if action == "list":
            groups = [g for k, v in args if k == "group" for g in v.split(",") if g]
            self._reply(200, list_params(cam.current_params(), groups))
        elif action == "update":
            lines: list[str] = []
            limits_changed = False
            for k, v in args:
                if k in ("action", "usergroup"):
                    continue
                name = k[5:] if k.startswith("root.") else k
                if name not in cam.params or name.startswith(READ_ONLY_PREFIXES):
                    lines.append(f"# Error: Error setting '{k}' to '{v}'!")
                    continue
                if name.startswith("PTZ.Limit.L1."):
                    try:
                        float(v)
                    except ValueError:
                        lines.append(f"# Error: Error setting '{k}' to '{v}'!")
                        continue
                    limits_changed = True
                cam.params[name] = v
            if limits_changed:
                p = cam.params
                cam.state.set_limits(
                    PtzLimits(
                        float(p["PTZ.Limit.L1.MinPan"]),
                        float(p["PTZ.Limit.L1.MaxPan"]),
                        float(p["PTZ.Limit.L1.MinTilt"]),
                        float(p["PTZ.Limit.L1.MaxTilt"]),
                        int(float(p["PTZ.Limit.L1.MinZoom"])),
                        int(float(p["PTZ.Limit.L1.MaxZoom"])),
                    )
                )
            self._reply(200, "\n".join(lines) + "\n" if lines else "OK\n")
        else:
            self._reply(200, f"# Error: Invalid action '{action}'\n")

    def _imagesize(self, args: list[tuple[str, str]], query: str) -> None:
        if self.cam.faults.no_imagesize:  # firmware without imagesize.cgi
            self._reply(404, NOT_FOUND_HTML.format(path=self.path.split("?", 1)[0]), "text/html; charset=ISO-8859-1")
            return
        a = dict(args)
        camera = a.get("camera", "1")
        if camera != "1":
            self._reply(200, f"<!-- Camera {camera} not available. -->\n")
            return
        try:
            w, h = self.cam.persona.parse_resolution(
                a.get("resolution", self.cam.params["Image.I0.Appearance.Resolution"]),
                a.get("squarepixel") == "1",
            )
        except ValueError as err:
            self._reply(200, f"<!-- {err} -->\n")
            return
        self._reply(200, f"image width = {w}\nimage height = {h}\n")

    def _videostatus(self, args: list[tuple[str, str]], query: str) -> None:
        self._reply(200, "Video 1 = video\n")

    # ---- video ----------------------------------------------------------------------------------------
    def _image_args(
        self, args: list[tuple[str, str]], video: bool
    ) -> tuple[int, int, int, str, dict[str, int]]:
        """Validate image/video arguments → (width, height, compression, overlay, stream options)."""
        a = {k.lower(): v for k, v in args}
        p = self.cam.params

        def integer(name: str, lo: int, hi: int, default: int) -> int:
            if name not in a:
                return default
            try:
                v = int(a[name])
            except ValueError as err:
                raise ValueError(f"Invalid {name}: {a[name]}") from err
            if not lo <= v <= hi:
                raise ValueError(f"Invalid {name}: {a[name]}")
            return v

        if a.get("camera", "1") != "1":
            raise ValueError(f"Camera {a['camera']} not available")
        squarepixel = integer("squarepixel", 0, 1, 0)
        w, h = self.cam.persona.parse_resolution(
            a.get("resolution", p["Image.I0.Appearance.Resolution"]), squarepixel == 1
        )
        compression = integer("compression", 0, 100, int(p["Image.I0.Appearance.Compression"]))
        integer("rotation", 0, 0, 0)
        opts = {"fps": self.cam.default_fps, "duration": 0, "nbrofframes": 0}
        if video:
            opts["fps"] = integer("fps", 0, MAX_FPS, self.cam.default_fps)
            opts["duration"] = integer("duration", 0, 10**7, 0)
            opts["nbrofframes"] = integer("nbrofframes", 0, 10**9, 0)
        parts = []
        if a.get("date") == "1":
            parts.append("%Y-%m-%d")
        if a.get("clock") == "1":
            parts.append("%H:%M:%S")
        overlay = time.strftime(" ".join(parts)) if parts else ""
        if a.get("text") == "1" and a.get("textstring"):
            overlay = (overlay + " " + a["textstring"]).strip()
        opts["clock"] = 1 if parts else 0
        return w, h, compression, overlay, opts

    def _image(self, args: list[tuple[str, str]], query: str) -> None:
        try:
            w, h, comp, overlay, _ = self._image_args(args, video=False)
        except ValueError as err:
            self._reply(400, f"Error:\n{err}\n")
            return
        cam = self.cam
        cam.snapshots_sent += 1
        jpeg = insert_comment(
            cam.frame_jpeg(w, h, comp, overlay), f"axsim seq={cam.snapshots_sent} t={time.time_ns()}".encode()
        )
        self._reply(200, jpeg, "image/jpeg", headers={"Cache-Control": "no-cache", "Pragma": "no-cache"})

    def _video(self, args: list[tuple[str, str]], query: str) -> None:
        try:
            w, h, comp, overlay, opts = self._image_args(args, video=True)
        except ValueError as err:
            self._reply(400, f"Error:\n{err}\n")
            return
        # As a real Axis answers video.cgi: HTTP/1.0, no Server and no Date, caching forbidden three ways.
        self.close_connection = True
        self.protocol_version = "HTTP/1.0"  # this connection only: it closes after the stream
        self.log_request(200)
        self.send_response_only(200)
        self.send_header("Cache-Control", "no-cache")
        self.send_header("Pragma", "no-cache")
        self.send_header("Expires", "Thu, 01 Dec 1994 16:00:00 GMT")
        self.send_header("Connection", "close")
        self.send_header("Content-Type", f"multipart/x-mixed-replace; boundary={BOUNDARY}")
        self.end_headers()
        self.cam._count("", 200)
        with contextlib.suppress(_StreamClosedError, OSError):
            self._stream(w, h, comp, overlay, opts)
        if self.cam._blackholed.is_set():
            self._hold_silently()  # the camera went mute mid-stream: no FIN, the client must time out

    def _stream(self, w: int, h: int, comp: int, overlay: str, opts: dict[str, int]) -> None:
        cam = self.cam
        fps, duration, nframes = opts["fps"], opts["duration"], opts["nbrofframes"]
        period = 1.0 / fps if fps > 0 else 0.0
        start = time.monotonic()
        next_t = start
        pending: collections.deque[tuple[float, bytes]] = collections.deque()
        seq = 0
        stalled = False
        last_jpeg: bytes | None = None
        last_render = -1.0
        stop = cam._stopping
        gen = cam._reboot_gen
        muted = cam._blackholed
        # a stream whose handler got here just after a reboot began reads the new generation: the blackhole flag
        # mutes it all the same (seen: a stream that kept sending through a packet-dropping reboot)
        while not stop.is_set() and gen == cam._reboot_gen and not muted.is_set():
            now = time.monotonic()
            if duration and now - start >= duration:
                return
            if nframes and seq >= nframes and not pending:
                return
            faults = cam.faults
            latency = faults.latency_ms / 1000.0
            produce = (not nframes or seq + len(pending) < nframes) and (
                (fps > 0 and now >= next_t) or (fps == 0 and not pending)
            )
            if produce:
                if fps == 0 and last_jpeg is not None and now - last_render < 1.0 / MAX_FPS:
                    jpeg = last_jpeg  # as fast as possible: resend the latest encoded frame
                else:
                    text = time.strftime(overlay) if opts.get("clock") else overlay
                    jpeg = cam.frame_jpeg(w, h, comp, text)
                    last_jpeg, last_render = jpeg, now
                pending.append((now + latency, jpeg))
                if fps > 0:
                    next_t += period
                    if next_t < now - period:  # fell behind (stall, slow client): do not burst
                        next_t = now + period
            while pending and pending[0][0] <= time.monotonic():
                _, jpeg = pending.popleft()
                seq += 1
                self._send_part(seq, jpeg, faults)
                cam.frames_sent += 1
                if faults.stall_after_frames and seq == faults.stall_after_frames and not stalled:
                    stalled = True
                    if stop.wait(faults.stall_seconds):
                        return
                    next_t = time.monotonic()
                if faults.drop_after_frames and seq >= faults.drop_after_frames:
                    # Drop mid-part: headers and half of the next JPEG, then close.
                    nxt = cam.frame_jpeg(w, h, comp, overlay)
                    self._write(_part_header(len(nxt)) + nxt[: len(nxt) // 2])
                    self.wfile.flush()
                    with contextlib.suppress(OSError):
                        self.connection.shutdown(socket.SHUT_RDWR)
                    raise _StreamClosedError
            now = time.monotonic()
            wake = [0.05]
            if fps > 0:
                wake.append(next_t - now)
            if pending:
                wake.append(pending[0][0] - now)
            delay = min(wake)
            if fps == 0 and not pending:
                continue  # as fast as possible
            if delay > 0:
                stop.wait(delay)

    def _send_part(self, seq: int, jpeg: bytes, faults: FaultConfig) -> None:
        data = insert_comment(jpeg, f"axsim seq={seq} t={time.time_ns()}".encode())
        if faults.truncate_every and seq % faults.truncate_every == 0:
            data = data[: max(16, len(data) // 2)]
        length = len(data)
        if faults.wrong_length_every and seq % faults.wrong_length_every == 0:
            length = max(0, length + faults.wrong_length_delta)
        part = (
            f"--{BOUNDARY}\r\nContent-Type: image/jpeg\r\nContent-Length: {length}\r\n\r\n".encode()
            + data
            + b"\r\n"
        )
        if faults.garbage_between_parts:
            part += _garbage()
        self._write(part)

    # ---- simulator control ---------------------------------------------------------------------------
    def _sim(self, path: str, args: list[tuple[str, str]]) -> None:
        cam = self.cam
        if path == "/sim/state":
            self._reply(200, json.dumps(cam.state_dict()), "application/json")
            return
        if path != "/sim/control":
            self._reply(404, NOT_FOUND_HTML.format(path=path), "text/html; charset=ISO-8859-1")
            return
        reboot = None
        reboot_opts: dict[str, Any] = {}
        try:
            changes: dict[str, Any] = {}
            for k, v in args:
                if k == "reset_faults":
                    cam.set_faults(FaultConfig())
                elif k == "reset_counts":
                    cam.reset_counts()
                elif k == "reboot":
                    reboot = float(v)
                elif k == "reboot_blackhole":
                    reboot_opts["blackhole"] = v.lower() in ("1", "true", "yes", "on")
                elif k == "reboot_errors_s":
                    reboot_opts["errors_s"] = float(v)
                elif k == "reboot_error":
                    if v not in REBOOT_ERROR_KINDS:
                        raise ValueError(f"reboot_error must be one of {REBOOT_ERROR_KINDS}")
                    reboot_opts["error_kind"] = v
                elif k == "nonce_lifetime":
                    cam.set_auth_options(nonce_lifetime_s=float(v))
                elif k == "challenge_style":
                    cam.set_auth_options(challenge_style=v)
                elif k == "teleport":
                    p, t, z = (float(x) for x in v.split(","))
                    cam.teleport(p, t, z)
                else:
                    changes[k] = v
            if changes:
                cam.set_faults(**changes)
        except (ValueError, TypeError) as err:
            self._reply(400, json.dumps({"error": str(err)}), "application/json")
            return
        self._reply(200, json.dumps(cam.state_dict()), "application/json")
        if reboot is not None:
            self.close_connection = True
            self.wfile.flush()
            secs = reboot
            threading.Thread(target=cam.reboot, args=(secs,), kwargs=reboot_opts, daemon=True).start()


def _part_header(length: int) -> bytes:
    return f"--{BOUNDARY}\r\nContent-Type: image/jpeg\r\nContent-Length: {length}\r\n\r\n".encode()


def _garbage() -> bytes:
    n = 8 + secrets.randbelow(56)
    raw = os.urandom(n).replace(b"-", b"x")
    return raw + b"\r\n"
