"""Learning what the camera is, and opening its stream for the reader. ROS-free.

:class:`CameraDiscovery` asks the camera once (:func:`~axis_ptz_ros2.camera_models.discover`: resolutions, pixel
aspect, model) from whichever comes first: its own start-up thread, which retries with back-off even while
nobody subscribes (a lazy node then advertises the camera's real sizes at once), or the reader's first
connection (:meth:`CameraDiscovery.open`, the reader's opener). While the camera is unreachable, a bare TCP
connect (:func:`probe_tcp`) decides whether an HTTP attempt is worth it: building the HTTP client for each
attempt costs ~10 ms of CPU, the probe ~0.1 ms.
"""

from __future__ import annotations

import socket
import threading
from collections.abc import Callable
from pathlib import Path

from axis_ptz_ros2.camera_models import CameraProfile, discover
from axis_ptz_ros2.config import default_config_path
from axis_ptz_ros2.streaming.meter import Backoff
from axis_ptz_ros2.streaming.reader import FrameSource
from axis_ptz_ros2.streaming.worker import Worker
from axis_ptz_ros2.vapix.camera_config import CameraConfig
from axis_ptz_ros2.vapix.client import VapixClient
from axis_ptz_ros2.vapix.errors import AuthError, AxisPtzError, CameraUnreachable, InvalidArgument
from axis_ptz_ros2.vapix.models import Resolution, VideoParams


def camera_model_path(value: str) -> str | None:
    """The camera-model file a ``camera_model`` parameter names (None: '' = learn it from the camera): the path as
    given when it exists, else the packaged file of that name (e.g. ``config/axis214.yaml`` from another working
    directory), else the path as given (loading it then says what is missing)."""
    if not value:
        return None
    p = Path(value).expanduser()
    if p.exists():
        return str(p)
    packaged = default_config_path(p.name)
    return str(packaged) if packaged.exists() else str(p)


def probe_tcp(config: CameraConfig) -> None:
    """Raise :class:`CameraUnreachable` unless the camera accepts a TCP connection (within its connect timeout)."""
    port = config.tcp_port
    try:
        socket.create_connection((config.host, port), timeout=config.connect_timeout_s).close()
    except OSError as err:
        raise CameraUnreachable(f"camera {config.host}:{port} not accepting connections ({err})") from err


ProfileCallback = Callable[[CameraProfile, bool], None]
"""``on_profile(profile, first)``: the camera answered (``first``: for the first time)."""


class CameraDiscovery:
    """Ask the camera what it is (once) and open its MJPEG stream (see the module docstring); thread-safe."""

    def __init__(
        self,
        client: VapixClient,
        model_file: str,
        params: Callable[[], VideoParams],
        *,
        on_profile: ProfileCallback,
        on_resolutions: Callable[[tuple[Resolution, ...]], None],
        on_problem: Callable[[str], None],
        first_delay_s: float = 0.5,
        max_delay_s: float = 10.0,
    ) -> None:
        """``params()``: the parameters in effect (read again once the camera's list is known: resolution ''
        becomes its largest); ``on_resolutions`` gets the camera's list once; ``on_problem`` the reason the
        camera could not say what it is (no credentials in it). Nothing runs until :meth:`start`."""
        self._client = client
        self._model_file = model_file
        self._params = params
        self._on_profile = on_profile
        self._on_resolutions = on_resolutions
        self._on_problem = on_problem
        self._backoff = Backoff(first_delay_s, max_delay_s)
        self._lock = threading.Lock()  # the start-up thread and the reader's first connection: one asks, one waits
        self._learned: tuple[Resolution, ...] = ()  # the camera's resolution list once asked successfully
        self._answered = False
        self._unreachable = False  # the last attempt could not connect: probe with TCP first
        self._worker = Worker("discovery", "axis-stream-learn", self._run)
        self._stopping = self._worker.stopping

    @property
    def learned(self) -> tuple[Resolution, ...]:
        """The camera's resolution list, () until learned."""
        return self._learned

    def start(self) -> None:
        """Start the start-up thread (once)."""
        self._worker.start()

    def stop(self, timeout: float = 2.0) -> None:
        """Stop and join the start-up thread."""
        self._worker.stop(timeout)

    def learn(self) -> tuple[Resolution, ...]:
        """The camera's resolution list: asked once (() if it could not say; asked again next time).
        Raises :class:`AuthError` when the login is refused."""
        with self._lock:
            if not self._learned:
                self._learned = self._ask()
                if self._learned:
                    self._on_resolutions(self._learned)
            return self._learned

    def open(self, params: VideoParams, read_timeout_s: float) -> FrameSource:
        """The reader's opener: probe an unreachable camera with TCP first, learn the camera (once), then open
        the stream (with the parameters in effect once the camera's list is known)."""
        if self._unreachable:
            probe_tcp(self._client.config)
        self._unreachable = False
        try:
            if not self._learned and self.learn():
                params = self._params()
            return self._client.open_mjpeg(params, read_timeout_s)
        except CameraUnreachable:
            self._unreachable = True
            raise

    def _run(self) -> None:
        """Learn the camera at start-up; retry with back-off until it answers (or the stream did it)."""
        while not self._stopping.is_set() and not self._learned:
            try:
                self.learn()
            except AuthError:
                return  # a refused login: the reader reports it and retries at its own pace (and learns then)
            if self._learned or self._stopping.wait(self._backoff.next()):
                return

    def _ask(self) -> tuple[Resolution, ...]:
        try:
            profile = discover(self._client, self._model_file)
        except AuthError:
            raise
        except AxisPtzError as err:
            if not isinstance(err, InvalidArgument):
                self._on_problem(f"cannot ask the camera what it is: {err}")
            return ()
        first = not self._answered
        self._answered = True
        self._on_profile(profile, first)
        return profile.optics.resolutions
