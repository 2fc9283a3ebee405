"""A faithful simulated Axis PTZ network camera: the device, its state and lifecycle (ROS-free).

:class:`SimulatedCamera` owns what a camera is: its persona, PTZ head, parameter tree, credentials
(:class:`~axis_ptz_ros2.sim.digest.CameraAuth`), picture (:class:`~axis_ptz_ros2.sim.frames.FrameSource`),
faults, request log, and its life: start, stop, reboot (with or without a black hole). It serves through any
number of :class:`Listener` s that it opens and closes together: the VAPIX HTTP server
(:mod:`axis_ptz_ros2.sim.http`) and, on personas that stream H.264, the RTSP one (:mod:`axis_ptz_ros2.sim.rtsp`).
Protocol handlers see it through :class:`~axis_ptz_ros2.sim.view.CameraView` (only the members they use), so
they never import this module.

Endpoints and behaviour follow vapix.md §11 (the simulator contract); see :mod:`axis_ptz_ros2.sim.http.server`.
"""

from __future__ import annotations

import dataclasses
import re
import ssl
import threading
import time
from types import TracebackType
from typing import Any, Protocol

from axis_ptz_ros2.sim.counts import PtzLogEntry, RequestCounts, RequestLog
from axis_ptz_ros2.sim.digest import AUTH_MODES, CHALLENGE_STYLES, NONCE_LIFETIME_S, CameraAuth, Verdict
from axis_ptz_ros2.sim.faults import REBOOT_ERROR_KINDS, Blackhole, FaultConfig
from axis_ptz_ros2.sim.frames import MAX_FPS, FrameSource
from axis_ptz_ros2.sim.http.server import HttpListener
from axis_ptz_ros2.sim.params import preset_params
from axis_ptz_ros2.sim.persona import Persona, persona
from axis_ptz_ros2.sim.ptz import PtzState, Speeds
from axis_ptz_ros2.sim.renderer import PtzRenderer
from axis_ptz_ros2.sim.rtsp.server import DEFAULT_SESSION_TIMEOUT_S, RtspListener
from axis_ptz_ros2.sim.scene import SimWorld, load_world
from axis_ptz_ros2.sim.tls import SelfSignedCertificate

__all__ = [
    "AUTH_MODES",
    "CHALLENGE_STYLES",
    "MAX_FPS",
    "NONCE_LIFETIME_S",
    "REBOOT_ERROR_KINDS",
    "Listener",
    "PtzLogEntry",
    "RequestCounts",
    "SimulatedCamera",
]


class Listener(Protocol):
    """A protocol server of the camera on one port, opened and closed with the camera."""

    @property
    def port(self) -> int:
        """The bound TCP port (the one asked for before the first :meth:`open`)."""
        ...

    def open(self) -> None:
        """Bind and serve (nothing if already open); raises :class:`OSError` while the port is busy."""
        ...

    def close(self, silently: bool = False) -> None:
        """Stop listening and close every connection (``silently``: leave them open and mute)."""
        ...


class SimulatedCamera:
    """A simulated Axis PTZ camera: ``start()`` it, talk VAPIX to ``base_url``, ``stop()`` it.

    ``model`` picks the persona (:mod:`axis_ptz_ros2.sim.persona`): ``axis214`` (default) or ``q6075``.
    ``auth`` is one of ``none`` (anonymous, the thesis' set-up), ``basic``, ``digest``, ``basic_digest``;
    None = the persona's default (214: none; q6075: digest). ``https`` None = the persona's default (214: off;
    q6075: on, with a self-signed certificate generated at start-up whose path is :attr:`ca_file`).
    ``rtsp_port``: where a persona that streams H.264 (q6075) serves RTSP (0: any free port, None: no RTSP);
    see :attr:`rtsp`. The password is never logged or shown in reprs.
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
        rtsp_port: int | None = 0,
        rtsp_session_timeout_s: float = DEFAULT_SESSION_TIMEOUT_S,
    ) -> None:
        self.persona = persona(model)
        auth = self.persona.default_auth if auth is None else auth
        if not re.fullmatch(r"[0-9A-Fa-f]{12}", mac):
            raise ValueError("mac must be 12 hex digits")
        self.mac = mac.upper()
        self.authenticator = CameraAuth(
            auth,
            f"AXIS_{self.mac}",
            user,
            password,
            nonce_lifetime_s=nonce_lifetime_s,
            challenge_style=challenge_style,
        )
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
        self.frames = FrameSource(self.world, self.state, self.persona.picture)
        self.requests = RequestLog()
        self._http = HttpListener(self, host, port)
        self._listeners: list[Listener] = [self._http]
        #: RTSP H.264 (sim/rtsp) on personas that list h264 in Properties.Image.Format; rtsp_port None: off
        self.rtsp: RtspListener | None = None
        if rtsp_port is not None and "h264" in self.params.get("Properties.Image.Format", "").split(","):
            self.rtsp = RtspListener(self, host, rtsp_port, rtsp_session_timeout_s)
            self._listeners.append(self.rtsp)
        self._running = False
        self._stopping = threading.Event()
        self._rebooting = threading.Event()
        self._reboot_gen = 0
        self._blackhole = Blackhole()
        self._errors_until = 0.0  #: monotonic end of the "web server up, video not yet" phase of a reboot
        self._error_kind = "503"
        self.video_ok_at: float | None = None  #: wall time (time.time()) video was served again after a reboot
        self._lifecycle = threading.Lock()
        self._counters = threading.Lock()  #: guards the two counters below (handler threads advance them)
        self._frames_sent = 0
        self._snapshots_sent = 0

    def __repr__(self) -> str:
        url = self.base_url if self.port else None
        return f"SimulatedCamera(model={self.persona.key!r}, url={url!r}, auth={self.auth!r}, user={self.user!r})"

    # ---- lifecycle ------------------------------------------------------------------------------------
    @property
    def renderer(self) -> PtzRenderer:
        """The view renderer (built on first use: the scene takes a moment)."""
        return self.frames.renderer

    def start(self) -> SimulatedCamera:
        """Build the scene and start serving (returns self)."""
        _ = self.renderer
        self._stopping.clear()
        self.forget_nonces()
        self._listen()
        return self

    def add_listener(self, listener: Listener) -> None:
        """Serve one more protocol (opened now if the camera runs, and at every start and reboot)."""
        with self._lifecycle:
            self._listeners.append(listener)
            if self._running:
                listener.open()

    def tls_context(self) -> ssl.SSLContext | None:
        """The TLS server context of the camera's HTTPS (None: plain HTTP); the certificate is made once."""
        if not self.https:
            return None
        if self._cert is None:
            self._cert = SelfSignedCertificate.generate(self.host, self.mac)
        return self._cert.server_context()

    def _listen(self) -> None:
        for listener in self._listeners:
            listener.open()
        self._running = True

    def _close_all(self, silently: bool = False) -> None:
        """Stop listening; close every connection (``silently``: leave them open and mute, as a camera that
        lost power does: its peers notice only through their own timeouts)."""
        self._running = False
        for listener in self._listeners:
            listener.close(silently)

    def stop(self) -> None:
        """Stop serving and close every connection (fast); removes the generated certificate."""
        with self._lifecycle:
            self._stopping.set()
            self._reboot_gen += 1
            self._rebooting.clear()
            self._close_all()
            self._blackhole.end()
            if self._cert is not None:
                self._cert.cleanup()
                self._cert = None

    def __enter__(self) -> SimulatedCamera:
        return self.start()

    def __exit__(self, et: type[BaseException] | None, ev: BaseException | None, tb: TracebackType | None) -> None:
        self.stop()

    @property
    def port(self) -> int:
        """The HTTP port (the real one after binding port 0)."""
        return self._http.port

    @property
    def base_url(self) -> str:
        """``http://host:port`` (``https://`` when serving HTTPS)."""
        return f"{'https' if self.https else 'http'}://{self.host}:{self.port}"

    @property
    def ca_file(self) -> str | None:
        """PEM file of the self-signed certificate served over HTTPS (a client's CA bundle), else None."""
        return str(self._cert.cert_file) if self._cert is not None else None

    @property
    def stopping(self) -> threading.Event:
        """Set while the camera is stopped: long-running handlers wait on it and end."""
        return self._stopping

    @property
    def generation(self) -> int:
        """Changes at every stop and reboot: a stream started in an older generation ends."""
        return self._reboot_gen

    @property
    def blackholed(self) -> bool:
        """Whether the camera drops packets (a reboot with ``blackhole=True``): handlers go mute."""
        return self._blackhole.active

    @property
    def reboot_error_kind(self) -> str:
        """What the web server answers while :meth:`serving_errors` (``503``, ``empty`` or ``401``)."""
        return self._error_kind

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
            if not self._running:
                raise RuntimeError("camera not running")
            if blackhole:
                self._blackhole.mute()  # before the generation changes: streams must go mute, not close
            self._rebooting.set()
            self._reboot_gen += 1
            gen = self._reboot_gen
            self.video_ok_at = None
            self._close_all(silently=blackhole)
            if blackhole:
                self._blackhole.hold(self.host, [listener.port for listener in self._listeners])

        def come_back() -> None:
            deadline = time.monotonic() + seconds
            while time.monotonic() < deadline:
                if self._stopping.wait(min(0.05, max(0.0, deadline - time.monotonic()))):
                    return
            with self._lifecycle:
                if gen != self._reboot_gen or self._stopping.is_set():
                    return
                self._blackhole.end()
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

    # ---- counters (handler threads advance them, under the camera's lock) -------------------------------
    def count_frame_sent(self) -> int:
        """One more MJPEG frame sent; the new total."""
        with self._counters:
            self._frames_sent += 1
            return self._frames_sent

    def count_snapshot(self) -> int:
        """One more ``image.cgi`` snapshot sent; the new total (its stamp)."""
        with self._counters:
            self._snapshots_sent += 1
            return self._snapshots_sent

    @property
    def frames_sent(self) -> int:
        """MJPEG frames sent since start-up."""
        with self._counters:
            return self._frames_sent

    @property
    def snapshots_sent(self) -> int:
        """``image.cgi`` snapshots sent since start-up."""
        with self._counters:
            return self._snapshots_sent

    # ---- ground truth and control ----------------------------------------------------------------------
    def current_params(self) -> dict[str, str]:
        """The parameter tree as listed now (a modern camera's presets appear under ``PTZ.Preset.P0``)."""
        if not self.persona.preset_params:
            return self.params
        presets = [(p.number, p.name, p.pan, p.tilt, p.zoom) for p in self.state.presets_snapshot()]
        tree = dict(self.params)
        tree.update(preset_params(presets, self.state.home))
        return tree

    def position(self) -> tuple[float, float, float]:
        """True current VAPIX (pan°, tilt°, zoom units), intermediate while moving."""
        return self.state.position()

    def teleport(self, pan: float, tilt: float, zoom: float) -> None:
        """Put the head at a pose instantly (test helper; clamped to the limits, stops all motion)."""
        self.state.arrive_now(pan, tilt, zoom)

    def frame_jpeg(self, width: int, height: int, compression: int, overlay: str = "") -> bytes:
        """The current view as JPEG (cached per view, quality and overlay text)."""
        return self.frames.frame_jpeg(width, height, compression, overlay)

    @property
    def request_counts(self) -> RequestCounts:
        """A snapshot copy of the request counters and the PTZ request log."""
        return self.requests.snapshot()

    def reset_counts(self) -> None:
        """Clear the request counters and log."""
        self.requests.reset()

    def set_faults(self, faults: FaultConfig | None = None, **changes: Any) -> FaultConfig:
        """Replace the fault configuration (``faults``) and/or change single faults; returns the new one."""
        base = faults if faults is not None else self.faults
        self.faults = base.replace(**changes) if changes else base
        return self.faults

    def state_dict(self) -> dict[str, Any]:
        """Ground truth for ``/sim/state``."""
        pan, tilt, zoom = self.position()
        counts = self.requests.as_dict()
        return {
            "pan": pan,
            "tilt": tilt,
            "zoom": zoom,
            "moving": self.state.moving(),
            "speed": self.state.speed,
            "faults": self.faults.as_dict(),
            "rebooting": self.rebooting,
            "blackholed": self.blackholed,
            "serving_errors": self.serving_errors(),
            "video_ok_at": self.video_ok_at,
            "nonce_lifetime_s": self.nonce_lifetime_s,
            "challenge_style": self.challenge_style,
            "frames_sent": self.frames_sent,
            "snapshots_sent": self.snapshots_sent,
            "renders": self.renderer.renders,
            "counts": counts,
        }

    # ---- auth (see CameraAuth) -------------------------------------------------------------------------
    @property
    def auth(self) -> str:
        """The authentication mode: ``none``, ``basic``, ``digest`` or ``basic_digest``."""
        return self.authenticator.mode

    @property
    def user(self) -> str:
        """The one user name the camera accepts."""
        return self.authenticator.user

    @property
    def realm(self) -> str:
        """The auth realm, ``AXIS_<MAC>``."""
        return self.authenticator.realm

    @property
    def nonce_lifetime_s(self) -> float:
        """Digest nonce lifetime (seconds)."""
        return self.authenticator.nonce_lifetime_s

    @property
    def challenge_style(self) -> str:
        """The 401 form: ``current`` or ``legacy``."""
        return self.authenticator.challenge_style

    def set_auth_options(self, *, nonce_lifetime_s: float | None = None, challenge_style: str | None = None) -> None:
        """Digest nonce lifetime and 401 form (:meth:`CameraAuth.set_options`)."""
        self.authenticator.set_options(nonce_lifetime_s=nonce_lifetime_s, challenge_style=challenge_style)

    def forget_nonces(self) -> None:
        """What a restart does: every nonce handed out so far becomes unknown."""
        self.authenticator.forget_nonces()

    def challenges(self, stale: bool = False) -> list[str]:
        """``WWW-Authenticate`` values for the current auth mode (``stale``: the nonce sent had expired)."""
        return self.authenticator.challenges(stale)

    def auth_result(self, header: str | None, method: str, uri: str) -> Verdict:
        """``ok``, ``stale`` (a correct Digest response to an expired nonce) or ``fail``."""
        return self.authenticator.check(header, method, uri)
