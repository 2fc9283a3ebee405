"""The joystick teleop's mapping: ``sensor_msgs/Joy`` axes and buttons → PTZ commands (pure, ROS-free).

:class:`JoyMap` is the configurable axis/button map (validated: a bad map is refused with the reason before
anything moves). :class:`JoyTeleop` is the state machine the node drives:

* :meth:`JoyTeleop.on_joy` — one Joy message: velocity from the sticks (dead zone, then rescaled so motion
  starts smoothly at the dead zone's edge), home / preset / zoom buttons on their *press* (rising edge);
* :meth:`JoyTeleop.tick` — called at the node's ``rate``: repeats the velocity while the dead-man button is
  held and Joy messages keep coming (the PTZ node stops a velocity command after its own ``velocity_timeout``
  without a new one), and sends **one** explicit stop when motion ends: stick centred, dead-man released, or
  no Joy message for ``timeout`` seconds (a joystick unplugged, a driver or a link that died).

Nothing moves without the dead-man button held (``deadman_button = -1`` disables that check, for a
simulator only). Signs: REP-103 (``PtzVelocity``: pan CCW/left positive, tilt up positive, zoom + = in); the
``joy`` package reports a stick pushed left or up as positive, so positive speeds turn the view the way the
stick points. A negative speed inverts an axis.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Final

#: characters VAPIX refuses in a preset name (vapix.md; the PTZ node checks again)
_BAD_PRESET_CHARS = set('"<>~:')
#: rad/s: the largest pan or tilt speed a map may ask for (either sign)
MAX_PAN_TILT_SPEED: Final = 10.0
#: the largest zoom speed, as a fraction of the camera's (either sign)
MAX_ZOOM_SPEED: Final = 1.0


@dataclass(frozen=True, slots=True)
class Velocity:
    """Continuous motion: rad/s (REP-103) and a −1…1 fraction of the camera's zoom speed."""

    pan_rate: float
    tilt_rate: float
    zoom_rate: float


@dataclass(frozen=True, slots=True)
class Stop:
    """Stop all motion now (``PtzVelocity`` zeros); ``reason`` for the log."""

    reason: str


@dataclass(frozen=True, slots=True)
class Home:
    """Go to pan 0, tilt 0, zoom 1 (``ptz/home``)."""


@dataclass(frozen=True, slots=True)
class GotoPreset:
    """Go to a preset stored in the camera (``ptz/preset`` action ``goto``)."""

    name: str


Command = Velocity | Stop | Home | GotoPreset


@dataclass(frozen=True, slots=True)
class JoyMap:
    """Axis and button indices (−1 = not used) and scales. Defaults: the ``joy`` package's
    ``game_controller_node`` layout (SDL game controller: axes 0/1 left stick, 2/3 right stick; buttons
    0 A, 1 B, 2 X, 3 Y, 9 left shoulder)."""

    pan_axis: int = 0
    tilt_axis: int = 1
    zoom_axis: int = 3
    pan_speed: float = 1.0  # rad/s at full deflection (negative = inverted)
    tilt_speed: float = 1.0  # rad/s at full deflection
    zoom_speed: float = 1.0  # fraction of the maximum zoom speed at full deflection (−1…1)
    deadzone: float = 0.1  # fraction of full deflection ignored around the centre
    deadman_button: int = 9
    home_button: int = 3
    zoom_in_button: int = -1
    zoom_out_button: int = -1
    preset_buttons: tuple[int, ...] = (0, 1, 2)
    preset_names: tuple[str, ...] = ("1", "2", "3")
    timeout: float = 0.5  # s without a Joy message before motion stops

    def __post_init__(self) -> None:
        problems = self.problems()
        if problems:
            raise ValueError("invalid joystick map: " + "; ".join(problems))

    def problems(self) -> list[str]:
        """Every reason this map cannot be used (empty when it is fine)."""
        out: list[str] = []
        for name in ("pan_axis", "tilt_axis", "zoom_axis"):
            v = getattr(self, name)
            if v < -1:
                out.append(f"{name}={v}: an index ≥ 0, or −1 for none")
        for name in ("deadman_button", "home_button", "zoom_in_button", "zoom_out_button"):
            v = getattr(self, name)
            if v < -1:
                out.append(f"{name}={v}: an index ≥ 0, or −1 for none")
        for name, lim in (
            ("pan_speed", MAX_PAN_TILT_SPEED),
            ("tilt_speed", MAX_PAN_TILT_SPEED),
            ("zoom_speed", MAX_ZOOM_SPEED),
        ):
            v = getattr(self, name)
            if not math.isfinite(v) or abs(v) > lim:
                out.append(f"{name}={v}: must be finite and within ±{lim:g}")
        if not (0.0 <= self.deadzone < 1.0):
            out.append(f"deadzone={self.deadzone}: must be in [0, 1)")
        if not (math.isfinite(self.timeout) and self.timeout > 0.0):
            out.append(f"timeout={self.timeout}: must be a positive number of seconds")
        if len(self.preset_buttons) != len(self.preset_names):
            out.append(
                f"preset_buttons has {len(self.preset_buttons)} entries but preset_names "
                f"{len(self.preset_names)}: one name per button"
            )
        for b in self.preset_buttons:
            if b < 0:
                out.append(f"preset button {b}: must be an index ≥ 0")
        for n in self.preset_names:
            if not n or len(n) > 31 or _BAD_PRESET_CHARS & set(n):
                out.append(f'preset name {n!r}: 1…31 characters, none of "<>~:')
        axes = [a for a in (self.pan_axis, self.tilt_axis, self.zoom_axis) if a >= 0]
        if len(axes) != len(set(axes)):
            out.append(f"pan/tilt/zoom axes {axes} must differ")
        used = [b for b in (self.home_button, self.zoom_in_button, self.zoom_out_button) if b >= 0]
        used += list(self.preset_buttons)
        if len(used) != len(set(used)):
            out.append(f"home/zoom/preset buttons {used} must differ")
        if self.deadman_button >= 0 and self.deadman_button in used:
            out.append(f"the dead-man button {self.deadman_button} cannot also be an action button")
        return out


def _axis(values: Sequence[float], index: int) -> float:
    if index < 0 or index >= len(values):
        return 0.0
    v = float(values[index])
    return max(-1.0, min(1.0, v)) if math.isfinite(v) else 0.0


def _button(values: Sequence[int], index: int) -> bool:
    return 0 <= index < len(values) and bool(values[index])


def shape(value: float, deadzone: float) -> float:
    """Dead zone, then rescale so the output grows from 0 at the dead zone's edge to ±1 at full deflection."""
    a = abs(value)
    if a <= deadzone:
        return 0.0
    return math.copysign((a - deadzone) / (1.0 - deadzone), value)


@dataclass
class JoyTeleop:
    """The teleop's state between Joy messages (see the module docstring). Times are monotonic seconds."""

    joy_map: JoyMap = field(default_factory=JoyMap)
    _last_joy: float | None = None
    _buttons: tuple[bool, ...] = ()
    _wanted: Velocity | None = None  # what the sticks ask for while enabled, None = no motion
    _moving: bool = False  # we have sent motion that has not been stopped yet
    warnings: list[str] = field(default_factory=list)

    @property
    def moving(self) -> bool:
        """True between a motion command and the stop that ends it."""
        return self._moving

    def _pressed(self, buttons: tuple[bool, ...], index: int) -> bool:
        """Rising edge of ``index`` between the previous message and this one."""
        if index < 0 or index >= len(buttons):
            return False
        before = index < len(self._buttons) and self._buttons[index]
        return buttons[index] and not before

    def on_joy(self, axes: Sequence[float], buttons: Sequence[int], now: float) -> list[Command]:
        """One Joy message → the commands to send now."""
        m = self.joy_map
        btn = tuple(bool(b) for b in buttons)
        self._check_sizes(len(axes), len(btn))
        enabled = m.deadman_button < 0 or _button(btn, m.deadman_button)
        out: list[Command] = []
        if enabled:
            if self._pressed(btn, m.home_button):
                out.append(Home())
            for b, name in zip(m.preset_buttons, m.preset_names, strict=True):
                if self._pressed(btn, b):
                    out.append(GotoPreset(name))
        self._buttons = btn
        self._last_joy = now
        wanted: Velocity | None = None
        if enabled:
            zoom = shape(_axis(axes, m.zoom_axis), m.deadzone) * m.zoom_speed
            if _button(btn, m.zoom_in_button):
                zoom = abs(m.zoom_speed)
            elif _button(btn, m.zoom_out_button):
                zoom = -abs(m.zoom_speed)
            v = Velocity(
                shape(_axis(axes, m.pan_axis), m.deadzone) * m.pan_speed,
                shape(_axis(axes, m.tilt_axis), m.deadzone) * m.tilt_speed,
                max(-1.0, min(1.0, zoom)),
            )
            if v.pan_rate or v.tilt_rate or v.zoom_rate:
                wanted = v
        if any(isinstance(c, Home | GotoPreset) for c in out):
            wanted = None  # a goto wins over the sticks in the same message; do not stop the move we asked for
            self._moving = False
        elif wanted is not None:
            if wanted != self._wanted:
                out.append(wanted)
            self._moving = True
        elif self._moving:
            out.append(Stop("dead-man button released" if not enabled else "sticks centred"))
            self._moving = False
        self._wanted = wanted
        return out

    def tick(self, now: float) -> list[Command]:
        """Periodic: repeat the wanted velocity while Joy is fresh; one stop when it goes silent."""
        if not self._moving or self._wanted is None:
            return []
        if self._last_joy is None or now - self._last_joy > self.joy_map.timeout:
            self._moving = False
            self._wanted = None
            self._buttons = ()  # a press after the silence counts as a new press
            return [Stop(f"no Joy message for {self.joy_map.timeout:g} s")]
        return [self._wanted]

    def _check_sizes(self, n_axes: int, n_buttons: int) -> None:
        m = self.joy_map
        for name in ("pan_axis", "tilt_axis", "zoom_axis"):
            i = getattr(m, name)
            if i >= n_axes:
                self._warn(f"{name}={i} but the Joy message has {n_axes} axes: that axis stays at 0")
        names = ["deadman_button", "home_button", "zoom_in_button", "zoom_out_button"]
        for name in names:
            i = getattr(m, name)
            if i >= n_buttons:
                self._warn(f"{name}={i} but the Joy message has {n_buttons} buttons: that button never fires")
        for i in m.preset_buttons:
            if i >= n_buttons:
                self._warn(f"preset button {i} but the Joy message has {n_buttons} buttons: it never fires")

    def _warn(self, text: str) -> None:
        if text not in self.warnings:
            self.warnings.append(text)
