"""The virtual PTZ head: a :class:`~axis_ptz_ros2.ptz.backend.PtzBackend` whose pose only exists in memory
(ROS-free).

Serves the same PTZ node as the real camera, so the virtual camera (a perspective view cut from the panorama,
:mod:`axis_ptz_ros2.virtual.render`) is driven by exactly the same topics and services. Everything is in ROS
units: REP-103 radians for pan/tilt, zoom units (1…9999) mapped to a field of view by a
:class:`~axis_ptz_ros2.optics.ZoomModel` (digital zoom).

Dynamics: absolute moves slew at a finite rate (default 180°/s, so ``moving`` and ``wait=true`` behave like
on the real head) or jump (``instant``); velocity commands integrate until the next command (the PTZ node's
velocity timeout stops them); pan turns freely when the limits cover the full circle (targets are reached the
short way round), otherwise every axis stops at its limit. Motion is integrated lazily from a monotonic clock
under one lock, so :meth:`VirtualPtzBackend.read_state` may be called from any thread at any time.
"""

from __future__ import annotations

import math
import re
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from axis_ptz_ros2.config import CameraModel
from axis_ptz_ros2.geometry import wrap_angle
from axis_ptz_ros2.optics import ZoomModel
from axis_ptz_ros2.ptz.backend import OutOfLimits, PresetInfo, PtzBackendError, PtzLimitsRos, PtzReading

PRESET_NAME = re.compile(r'^[^"<>~:]{1,31}$')  #: the Axis rule for server preset names (vapix.md §4)
_EPS = 1e-12


@dataclass(frozen=True, slots=True)
class VirtualDynamics:
    """How fast the virtual head moves.

    ``max_pan_rate``/``max_tilt_rate`` (rad/s) bound absolute slews (scaled by a move's ``speed`` fraction) and
    clip velocity commands; ``zoom_travel_s`` is the time from the widest to the narrowest zoom at full zoom
    speed; ``instant`` makes absolute moves (and home/preset) jump to the target.
    """

    max_pan_rate: float = math.radians(180.0)
    max_tilt_rate: float = math.radians(180.0)
    zoom_travel_s: float = 0.5
    instant: bool = False

    def __post_init__(self) -> None:
        """Validate."""
        if not (self.max_pan_rate > 0.0 and self.max_tilt_rate > 0.0):
            raise ValueError("maximum pan and tilt rates must be positive")
        if not self.zoom_travel_s > 0.0:
            raise ValueError("zoom_travel_s must be positive")

    @staticmethod
    def from_dict(d: dict[str, Any]) -> VirtualDynamics:
        """From a mapping with ``pan_dps``, ``tilt_dps`` (degrees/s), ``zoom_travel_s`` and ``instant``."""
        base = VirtualDynamics()
        return VirtualDynamics(
            max_pan_rate=math.radians(float(d.get("pan_dps", math.degrees(base.max_pan_rate)))),
            max_tilt_rate=math.radians(float(d.get("tilt_dps", math.degrees(base.max_tilt_rate)))),
            zoom_travel_s=float(d.get("zoom_travel_s", base.zoom_travel_s)),
            instant=bool(d.get("instant", base.instant)),
        )


def virtual_limits(
    zoom_model: ZoomModel, tilt_min: float = -math.pi / 2.0, tilt_max: float = math.pi / 2.0
) -> PtzLimitsRos:
    """Limits of a virtual head: pan −π…π (full turn), tilt ``tilt_min``…``tilt_max`` (rad), the zoom model's
    zoom range."""
    return PtzLimitsRos(-math.pi, math.pi, tilt_min, tilt_max, float(zoom_model.min_zoom), float(zoom_model.max_zoom))


def limits_from_model(model: CameraModel) -> PtzLimitsRos:
    """The camera model's ``limits`` (VAPIX degrees, converted by its convention) in ROS units."""
    lim = model.limits
    p0, p1, t0, t1 = model.convention.limits_to_ros(
        lim.min_pan_deg, lim.max_pan_deg, lim.min_tilt_deg, lim.max_tilt_deg
    )
    return PtzLimitsRos(p0, p1, t0, t1, float(lim.min_zoom), float(lim.max_zoom))


def dynamics_from_model(model: CameraModel, dynamics: Mapping[str, Any] | None = None) -> VirtualDynamics:
    """Slew/velocity rates from the model's ``max_speed``; ``zoom_travel_s`` and ``instant`` from the
    ``dynamics`` mapping (the ``dynamics`` section of ``config/virtual_camera.yaml``)."""
    d: dict[str, Any] = {"pan_dps": model.max_pan_speed_dps, "tilt_dps": model.max_tilt_speed_dps}
    d.update({k: v for k, v in (dynamics or {}).items() if k in ("zoom_travel_s", "instant")})
    return VirtualDynamics.from_dict(d)


@dataclass(frozen=True, slots=True)
class _Preset:
    number: int
    pan: float
    tilt: float
    zoom: float


class VirtualPtzBackend:
    """An in-memory PTZ head in ROS units (see :class:`~axis_ptz_ros2.ptz.backend.PtzBackend`). Thread-safe."""

    def __init__(
        self,
        limits: PtzLimitsRos,
        zoom_model: ZoomModel,
        dynamics: VirtualDynamics | None = None,
        *,
        home: tuple[float, float, float] | None = None,
        initial: tuple[float, float, float] | None = None,
        clock: Callable[[], float] = time.monotonic,
        wall_clock_ns: Callable[[], int] = time.time_ns,
    ) -> None:
        """``home`` and ``initial`` are (pan rad, tilt rad, zoom units); both default to (0, 0, zoom_min)
        clamped into the limits. ``clock`` (s, monotonic) drives the motion, ``wall_clock_ns`` stamps readings.
        """
        if limits.pan_min > limits.pan_max or limits.tilt_min > limits.tilt_max:
            raise ValueError("empty pan or tilt range")
        if limits.zoom_min >= limits.zoom_max:
            raise ValueError("zoom_max must be greater than zoom_min")
        self._limits = limits
        self.zoom_model = zoom_model
        self.dynamics = dynamics or VirtualDynamics()
        self._clock = clock
        self._wall_ns = wall_clock_ns
        default = self._clamp_pose(0.0, 0.0, limits.zoom_min)
        self._home = self._clamp_pose(*home) if home is not None else default
        self._lock = threading.Lock()
        self._pose = list(self._clamp_pose(*initial) if initial is not None else default)
        self._target: list[float | None] = [None, None, None]
        self._slew = [self.dynamics.max_pan_rate, self.dynamics.max_tilt_rate, self._zoom_rate_max]
        self._rate = [0.0, 0.0, 0.0]  # velocity mode: rad/s, rad/s, zoom units/s
        self._t = clock()
        self._presets: dict[str, _Preset] = {}
        self._closed = False

    def __repr__(self) -> str:
        """Short description."""
        return f"VirtualPtzBackend(pan {self._limits.pan_min:.3f}..{self._limits.pan_max:.3f} rad)"

    # -- helpers (call with the lock held where they touch state) -------------------------------------
    @property
    def _zoom_rate_max(self) -> float:
        return (self._limits.zoom_max - self._limits.zoom_min) / self.dynamics.zoom_travel_s

    def _clamp_pose(self, pan: float, tilt: float, zoom: float) -> tuple[float, float, float]:
        lim = self._limits
        p = wrap_angle(pan) if lim.full_turn else min(max(pan, lim.pan_min), lim.pan_max)
        return (
            p,
            min(max(tilt, lim.tilt_min), lim.tilt_max),
            min(max(zoom, lim.zoom_min), lim.zoom_max),
        )

    def _check_open(self) -> None:
        if self._closed:
            raise PtzBackendError("the virtual head is closed")

    def _advance(self) -> None:
        """Integrate the motion up to now."""
        now = self._clock()
        dt = now - self._t
        self._t = now
        if dt <= 0.0:
            return
        lim = self._limits
        lo = (lim.pan_min, lim.tilt_min, lim.zoom_min)
        hi = (lim.pan_max, lim.tilt_max, lim.zoom_max)
        for i in range(3):
            pos = self._pose[i]
            if self._rate[i] != 0.0:
                pos += self._rate[i] * dt
            else:
                target = self._target[i]
                if target is None:
                    continue
                err = wrap_angle(target - pos) if (i == 0 and lim.full_turn) else target - pos
                step = self._slew[i] * dt
                if abs(err) <= step:
                    pos, self._target[i] = pos + err, None
                else:
                    pos += math.copysign(step, err)
            self._pose[i] = wrap_angle(pos) if i == 0 and lim.full_turn else min(max(pos, lo[i]), hi[i])

    def _axis_moving(self, i: int) -> bool:
        if self._target[i] is not None:
            return True
        r = self._rate[i]
        if r == 0.0:
            return False
        lim = self._limits
        if i == 0 and lim.full_turn:
            return True
        lo = (lim.pan_min, lim.tilt_min, lim.zoom_min)[i]
        hi = (lim.pan_max, lim.tilt_max, lim.zoom_max)[i]
        return not ((r < 0.0 and self._pose[i] <= lo + _EPS) or (r > 0.0 and self._pose[i] >= hi - _EPS))

    def _goto(self, pan: float | None, tilt: float | None, zoom: float | None, speed: float | None) -> None:
        """Start an absolute move (lock held, limits already checked): cancels velocity motion."""
        self._advance()
        self._rate = [0.0, 0.0, 0.0]
        frac = 1.0
        if speed is not None and math.isfinite(speed) and speed > 0.0:
            frac = min(1.0, speed)
        self._slew = [self.dynamics.max_pan_rate * frac, self.dynamics.max_tilt_rate * frac, self._zoom_rate_max]
        cur = self._pose
        goal = self._clamp_pose(
            cur[0] if pan is None else pan, cur[1] if tilt is None else tilt, cur[2] if zoom is None else zoom
        )
        for i, given in enumerate((pan, tilt, zoom)):
            if given is None:
                self._target[i] = None  # an axis not commanded stops where it is
            elif self.dynamics.instant:
                self._pose[i], self._target[i] = goal[i], None
            else:
                self._target[i] = goal[i]

    # -- PtzBackend --------------------------------------------------------------------------------------
    def limits(self) -> PtzLimitsRos:
        """The configured limits."""
        return self._limits

    def read_state(self) -> PtzReading:
        """The current pose, stamped with the wall clock."""
        with self._lock:
            self._check_open()
            self._advance()
            pan, tilt, zoom = self._pose
        return PtzReading(pan, tilt, zoom, self._wall_ns())

    def pose(self) -> tuple[float, float, float, bool]:
        """(pan rad, tilt rad, zoom units, moving) now."""
        with self._lock:
            self._advance()
            moving = any(self._axis_moving(i) for i in range(3))
            return self._pose[0], self._pose[1], self._pose[2], moving

    @property
    def moving(self) -> bool:
        """Whether any axis is slewing towards a target or turning under a velocity command."""
        return self.pose()[3]

    def move_to(self, pan: float | None, tilt: float | None, zoom: float | None, speed: float | None = None) -> None:
        """Absolute move; None keeps an axis. Raises :class:`OutOfLimits` (nothing moves) when an axis is out
        of range; pan is wrapped on a full-turn head."""
        reason = self._limits.violation(pan, tilt, zoom)
        if reason is not None:
            raise OutOfLimits(reason)
        with self._lock:
            self._check_open()
            self._goto(pan, tilt, zoom, speed)

    def velocity(self, pan_rate: float, tilt_rate: float, zoom_rate: float) -> None:
        """Continuous motion: rad/s clipped to the maximum rates, zoom −1…1 of the full zoom speed; all zero
        stops. Cancels any absolute move."""
        if not all(math.isfinite(v) for v in (pan_rate, tilt_rate, zoom_rate)):
            raise PtzBackendError("velocity components must be finite")
        d = self.dynamics
        rates = [
            max(-d.max_pan_rate, min(d.max_pan_rate, pan_rate)),
            max(-d.max_tilt_rate, min(d.max_tilt_rate, tilt_rate)),
            max(-1.0, min(1.0, zoom_rate)) * self._zoom_rate_max,
        ]
        with self._lock:
            self._check_open()
            self._advance()
            self._target = [None, None, None]
            self._rate = rates

    def stop(self) -> None:
        """Stop every axis where it is."""
        with self._lock:
            self._check_open()
            self._advance()
            self._target = [None, None, None]
            self._rate = [0.0, 0.0, 0.0]

    def home(self) -> None:
        """Go to the home pose."""
        with self._lock:
            self._check_open()
            self._goto(*self._home, None)

    def goto_preset(self, name: str) -> None:
        """Go to a stored preset (PtzBackendError if there is none of that name)."""
        with self._lock:
            self._check_open()
            p = self._presets.get(name)
            if p is None:
                raise PtzBackendError(f"no preset named {name!r}")
            self._goto(p.pan, p.tilt, p.zoom, None)

    def set_preset(self, name: str) -> None:
        """Store the current pose under ``name`` (replacing a preset of that name, keeping its number)."""
        if not PRESET_NAME.match(name):
            raise PtzBackendError(f'invalid preset name {name!r}: 1..31 characters, none of "<>~:')
        with self._lock:
            self._check_open()
            self._advance()
            old = self._presets.get(name)
            if old is not None:
                number = old.number
            else:
                used = {p.number for p in self._presets.values()}
                number = next(n for n in range(1, len(used) + 2) if n not in used)
            self._presets[name] = _Preset(number, *self._pose)

    def remove_preset(self, name: str) -> None:
        """Delete a preset (PtzBackendError if there is none of that name)."""
        with self._lock:
            self._check_open()
            if self._presets.pop(name, None) is None:
                raise PtzBackendError(f"no preset named {name!r}")

    def list_presets(self) -> list[PresetInfo]:
        """Stored presets, by number."""
        with self._lock:
            self._check_open()
            return sorted((PresetInfo(p.number, n) for n, p in self._presets.items()), key=lambda p: p.number)

    def close(self) -> None:
        """Refuse further commands (idempotent)."""
        with self._lock:
            self._closed = True
