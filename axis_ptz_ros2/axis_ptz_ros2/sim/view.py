"""What the simulated camera's protocol handlers see of the camera: :class:`CameraView` (ROS-free, no sockets).

The HTTP side (:mod:`axis_ptz_ros2.sim.http`), the RTSP side (:mod:`axis_ptz_ros2.sim.rtsp`) and the control
surface (:mod:`axis_ptz_ros2.sim.control`) are typed against this interface, not against
:class:`~axis_ptz_ros2.sim.camera.SimulatedCamera`, which implements it: the camera owns its listeners, the
listeners know only this view, and neither module needs the other to be read or type-checked.

The members are the ones the handlers use and nothing more. Counters the handlers advance go through methods
(:meth:`CameraView.count_frame_sent`, :meth:`CameraView.count_snapshot`) that take the camera's lock.
"""

from __future__ import annotations

import ssl
import threading
from typing import Any, Protocol

from axis_ptz_ros2.sim.counts import RequestLog
from axis_ptz_ros2.sim.digest import Verdict
from axis_ptz_ros2.sim.faults import FaultConfig
from axis_ptz_ros2.sim.persona import Persona
from axis_ptz_ros2.sim.ptz import PtzState
from axis_ptz_ros2.sim.renderer import PtzRenderer

__all__ = ["CameraView"]


class CameraView(Protocol):
    """The simulated camera as its HTTP, RTSP and control handlers see it."""

    # ---- what the camera is ----------------------------------------------------------------------------
    @property
    def persona(self) -> Persona:
        """The model the camera simulates (resolutions, frame rate, Server header, picture model)."""
        ...

    @property
    def mac(self) -> str:
        """The MAC address (12 upper-case hex digits): the RTCP CNAME carries it."""
        ...

    @property
    def params(self) -> dict[str, str]:
        """The parameter tree (``param.cgi?action=update`` changes it in place)."""
        ...

    @property
    def state(self) -> PtzState:
        """The PTZ head (``ptz.cgi`` and ``ptzconfig.cgi`` drive it)."""
        ...

    @property
    def default_fps(self) -> int:
        """The frame rate of a stream that asks for none."""
        ...

    @property
    def renderer(self) -> PtzRenderer:
        """The view renderer (RTSP sessions render through it)."""
        ...

    @property
    def faults(self) -> FaultConfig:
        """The faults in force now."""
        ...

    @property
    def requests(self) -> RequestLog:
        """The request counters and logs (thread-safe)."""
        ...

    def current_params(self) -> dict[str, str]:
        """The parameter tree as listed now (presets included)."""
        ...

    def position(self) -> tuple[float, float, float]:
        """True current VAPIX (pan°, tilt°, zoom units)."""
        ...

    def frame_jpeg(self, width: int, height: int, compression: int, overlay: str = "") -> bytes:
        """The current view as JPEG."""
        ...

    def tls_context(self) -> ssl.SSLContext | None:
        """The TLS server context of the camera's HTTPS (None: plain HTTP)."""
        ...

    # ---- counters (under the camera's lock) ------------------------------------------------------------
    def count_frame_sent(self) -> int:
        """One more MJPEG frame sent; the new total."""
        ...

    def count_snapshot(self) -> int:
        """One more ``image.cgi`` snapshot sent; the new total (its stamp)."""
        ...

    # ---- lifecycle as the handlers see it --------------------------------------------------------------
    @property
    def stopping(self) -> threading.Event:
        """Set while the camera is stopped: long-running handlers wait on it and end."""
        ...

    @property
    def generation(self) -> int:
        """Changes at every stop and reboot: a stream started in an older generation ends."""
        ...

    @property
    def blackholed(self) -> bool:
        """Whether the camera drops packets: handlers go mute."""
        ...

    @property
    def reboot_error_kind(self) -> str:
        """What the web server answers while :meth:`serving_errors` (``503``, ``empty`` or ``401``)."""
        ...

    def serving_errors(self) -> bool:
        """Whether the camera is in the "web server up, video not yet" phase of a reboot."""
        ...

    # ---- auth ------------------------------------------------------------------------------------------
    @property
    def challenge_style(self) -> str:
        """The 401 form: ``current`` or ``legacy``."""
        ...

    def challenges(self, stale: bool = False) -> list[str]:
        """``WWW-Authenticate`` values for the current auth mode."""
        ...

    def auth_result(self, header: str | None, method: str, uri: str) -> Verdict:
        """``ok``, ``stale`` or ``fail``."""
        ...

    # ---- the test-only control surface (``/sim/…``) ----------------------------------------------------
    def state_dict(self) -> dict[str, Any]:
        """Ground truth for ``/sim/state``."""
        ...

    def set_faults(self, faults: FaultConfig | None = None, **changes: Any) -> FaultConfig:
        """Replace the fault configuration and/or change single faults; returns the new one."""
        ...

    def reset_counts(self) -> None:
        """Clear the request counters and log."""
        ...

    def set_auth_options(self, *, nonce_lifetime_s: float | None = None, challenge_style: str | None = None) -> None:
        """Digest nonce lifetime and 401 form."""
        ...

    def teleport(self, pan: float, tilt: float, zoom: float) -> None:
        """Put the head at a pose instantly."""
        ...

    def reboot(
        self, seconds: float, *, blackhole: bool = False, errors_s: float = 0.0, error_kind: str = "503"
    ) -> None:
        """Simulate a reboot (returns immediately)."""
        ...
