"""Drive-safe zoom (ROS-free): cap the zoom while the robot moves, restore the operator's zoom when it stops.

The thesis found zoom above about 4000 VAPIX units unusable on a robot driving over cobblestones (the image
shakes too much to be read). :class:`DriveSafeZoom` turns the robot's speed (from odometry or ``cmd_vel``) into
"capped or not": capped as soon as the linear speed exceeds ``speed_mps`` or the turn rate exceeds ``turn_rps``,
released once the robot has been below both for ``hold_s`` (so a short stop at a kerb does not make the zoom
pump in and out). No speed message for ``hold_s`` counts as stopped. What the cap does to the head is
:class:`~axis_ptz_ros2.ptz.commander.Commander`'s job.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class DriveSafeConfig:
    """Thresholds (m/s, rad/s), the cap (VAPIX zoom units) and the hold time (s)."""

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
