"""Drive-safe zoom (ROS-free): cap the zoom while the robot moves, restore the operator's zoom when it stops.

The thesis found zoom above about 4000 VAPIX units unusable on a robot driving over cobblestones (the image
shakes too much to be read). :class:`DriveSafeZoom` turns the robot's speed (from odometry or ``cmd_vel``) into
"capped or not": capped as soon as the linear speed exceeds ``speed_mps`` or the turn rate exceeds ``turn_rps``,
released once the robot has been below both for ``hold_s`` (so a short stop at a kerb does not make the zoom
pump in and out). No speed message for ``hold_s`` counts as stopped. :class:`DriveSafeCap` hands that verdict to
the :class:`~axis_ptz_ros2.ptz.commander.Commander`, whose job is what the cap does to the head.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

from axis_ptz_ros2.ptz.commander import Commander


@dataclass(frozen=True, slots=True)
class DriveSafeConfig:
    """Thresholds (m/s, rad/s), the cap (VAPIX zoom units) and the hold time (s): a frozen snapshot of the
    node's ``drive_*`` parameters. The defaults here are the parameters' defaults."""

    speed_mps: float = 0.2
    turn_rps: float = 0.3
    zoom_cap: float = 4000.0
    hold_s: float = 2.0

    def __post_init__(self) -> None:
        for name in ("speed_mps", "turn_rps", "zoom_cap", "hold_s"):
            v = getattr(self, name)
            if not math.isfinite(v) or v < 0.0:
                raise ValueError(f"drive-safe {name} must be finite and >= 0, not {v}")


class DriveSafeZoom:
    """Capped while the robot moves faster than the thresholds, plus ``hold_s`` after it stopped."""

    def __init__(self, config: DriveSafeConfig, clock: Callable[[], float] = time.monotonic) -> None:
        """``clock``: monotonic seconds."""
        self.config = config
        self._clock = clock
        self._lock = threading.Lock()
        self._capped = False
        self._last_moving = -math.inf
        self.last_speed = (0.0, 0.0)  # m/s, rad/s of the newest message

    @property
    def capped(self) -> bool:
        """Whether the cap is in force (call :meth:`tick` or :meth:`update` to advance time)."""
        with self._lock:
            return self._capped

    def moving(self, linear_mps: float, angular_rps: float) -> bool:
        """Above a threshold (a non-finite speed counts as moving: the safe side)."""
        if not (math.isfinite(linear_mps) and math.isfinite(angular_rps)):
            return True
        return abs(linear_mps) > self.config.speed_mps or abs(angular_rps) > self.config.turn_rps

    def update(self, linear_mps: float, angular_rps: float) -> bool:
        """A new speed (linear: the planar speed's magnitude, angular: yaw rate). Returns the capped state."""
        now = self._clock()
        with self._lock:
            self.last_speed = (linear_mps, angular_rps)
            if self.moving(linear_mps, angular_rps):
                self._last_moving = now
                self._capped = True
            elif self._capped and now - self._last_moving >= self.config.hold_s:
                self._capped = False
            return self._capped

    def tick(self) -> bool:
        """Advance time without a message (release after the hold). Returns the capped state."""
        now = self._clock()
        with self._lock:
            if self._capped and now - self._last_moving >= self.config.hold_s:
                self._capped = False
            return self._capped

    def set_config(self, config: DriveSafeConfig) -> None:
        """New thresholds/cap/hold (takes effect with the next update or tick)."""
        with self._lock:
            self.config = config


class DriveSafeCap:
    """Applies a :class:`DriveSafeZoom`'s verdict to the commander's zoom cap (only on a change), and a new
    configuration at once (a new cap value replaces the one in force)."""

    def __init__(self, zoom: DriveSafeZoom, cmd: Commander, log: Callable[[str], None] = lambda _m: None) -> None:
        """``log``: told each change for people ("robot moving: zoom capped at 4000 (… sent)")."""
        self.zoom = zoom
        self._cmd = cmd
        self._log = log

    @property
    def config(self) -> DriveSafeConfig:
        """The configuration in force."""
        return self.zoom.config

    def on_speed(self, linear_mps: float, angular_rps: float) -> None:
        """A new speed of the robot (planar speed, yaw rate)."""
        self._apply(self.zoom.update(linear_mps, angular_rps))

    def tick(self) -> None:
        """Advance time without a speed message (releases the cap after the hold time)."""
        self._apply(self.zoom.tick())

    def reconfigure(self, config: DriveSafeConfig) -> None:
        """New thresholds/cap/hold; a cap in force takes the new value now."""
        self.zoom.set_config(config)
        if self._cmd.zoom_cap is not None:
            self._cmd.set_zoom_cap(None)
            self._cmd.set_zoom_cap(config.zoom_cap)

    def _apply(self, capped: bool) -> None:
        cap = self.zoom.config.zoom_cap if capped else None
        if cap == self._cmd.zoom_cap:
            return
        order = self._cmd.set_zoom_cap(cap)
        what = f"robot moving: zoom capped at {cap:g}" if cap is not None else "robot stopped: zoom cap lifted"
        sent = f" ({order.label} sent)" if order is not None and not order.refused else ""
        self._log(what + sent)
