"""The simulator's test-only control surface, ``/sim/state`` and ``/sim/control?…`` (ROS-free, no sockets).

Never authenticated and never faulted (vapix.md §11). ``/sim/state`` is the ground truth as JSON;
``/sim/control`` sets faults (any :class:`~axis_ptz_ros2.sim.faults.FaultConfig` field), ``reset_faults``,
``reset_counts``, ``nonce_lifetime``, ``challenge_style``, ``teleport=pan,tilt,zoom`` and ``reboot=<seconds>``
(with ``reboot_blackhole``, ``reboot_errors_s``, ``reboot_error``), then answers with the new state. A reboot
starts only after that reply went out: :meth:`ControlReply.start_reboot`.
"""

from __future__ import annotations

import json
import math
import threading
from dataclasses import dataclass, field
from typing import Any

from axis_ptz_ros2.sim.digest import CHALLENGE_STYLES
from axis_ptz_ros2.sim.faults import REBOOT_ERROR_KINDS, FaultConfig
from axis_ptz_ros2.sim.view import CameraView


@dataclass(frozen=True)
class ControlReply:
    """What to answer (``status``, JSON ``body``; 404: not a control path) and a reboot to start afterwards."""

    status: int
    body: str = ""
    reboot_s: float | None = None
    reboot_opts: dict[str, Any] = field(default_factory=dict)

    def start_reboot(self, cam: CameraView) -> None:
        """Start the requested reboot, if any (in the background: it returns at once)."""
        if self.reboot_s is not None:
            threading.Thread(target=cam.reboot, args=(self.reboot_s,), kwargs=self.reboot_opts, daemon=True).start()


def _truthy(v: str) -> bool:
    return v.lower() in ("1", "true", "yes", "on")


def _seconds(name: str, value: str) -> float:
    """A duration argument: a finite number of seconds >= 0 (a refused one gets a 400 with this reason)."""
    s = float(value)
    if not math.isfinite(s) or s < 0:
        raise ValueError(f"{name} must be >= 0 and finite (seconds), got {value!r}")
    return s


def _pose(value: str) -> tuple[float, float, float]:
    """``teleport=pan,tilt,zoom``: three finite numbers (VAPIX degrees and zoom units)."""
    p, t, z = (float(x) for x in value.split(","))
    if not all(math.isfinite(v) for v in (p, t, z)):
        raise ValueError(f"pose must be finite: {p}, {t}, {z}")
    return p, t, z


def _nonce_lifetime(value: str) -> float:
    s = float(value)
    if not s > 0:
        raise ValueError("nonce_lifetime_s must be > 0")
    return s


def handle(cam: CameraView, path: str, args: list[tuple[str, str]]) -> ControlReply:
    """Answer a ``/sim/…`` request (``args``: query string pairs, in order). Every argument is checked before any is
    applied: a request with one bad argument is refused (400, the reason) and changes nothing."""
    if path == "/sim/state":
        return ControlReply(200, json.dumps(cam.state_dict()))
    if path != "/sim/control":
        return ControlReply(404)
    reboot = None
    reboot_opts: dict[str, Any] = {}
    auth: dict[str, Any] = {}
    pose: tuple[float, float, float] | None = None
    reset_faults = reset_counts = False
    try:
        changes: dict[str, Any] = {}
        for k, v in args:
            if k == "reset_faults":
                reset_faults, changes = True, {}  # faults named before it are reset with the rest
            elif k == "reset_counts":
                reset_counts = True
            elif k == "reboot":
                reboot = _seconds(k, v)
            elif k == "reboot_blackhole":
                reboot_opts["blackhole"] = _truthy(v)
            elif k == "reboot_errors_s":
                reboot_opts["errors_s"] = _seconds(k, v)
            elif k == "reboot_error":
                if v not in REBOOT_ERROR_KINDS:
                    raise ValueError(f"reboot_error must be one of {REBOOT_ERROR_KINDS}")
                reboot_opts["error_kind"] = v
            elif k == "nonce_lifetime":
                auth["nonce_lifetime_s"] = _nonce_lifetime(v)
            elif k == "challenge_style":
                if v not in CHALLENGE_STYLES:
                    raise ValueError(f"challenge_style must be one of {CHALLENGE_STYLES}")
                auth["challenge_style"] = v
            elif k == "teleport":
                pose = _pose(v)
            else:
                changes[k] = v
        base = FaultConfig() if reset_faults else cam.faults
        faults = base.replace(**changes) if changes else base  # checks every fault named
    except (ValueError, TypeError) as err:
        return ControlReply(400, json.dumps({"error": str(err)}))
    # every argument is good: apply them
    if reset_faults or changes:
        cam.set_faults(faults)
    if reset_counts:
        cam.reset_counts()
    if auth:
        cam.set_auth_options(**auth)
    if pose is not None:
        cam.teleport(*pose)
    return ControlReply(200, json.dumps(cam.state_dict()), reboot, reboot_opts)
