"""The values of PTZ commands (ROS-free): an :class:`Order` as submitted, a :class:`Progress` step of following one, the
field checks of a command, the arrival tolerances and the commander's counters.

A *spec* says how a new target follows from the target the camera last accepted and the measured pose; the
:class:`~axis_ptz_ros2.ptz.commander.Commander` composes and evaluates them (its module docstring says why).
Units: REP-103 radians in joint coordinates (the calibrated encoder offsets applied), VAPIX zoom units.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

from axis_ptz_ros2.geometry import wrap_angle
from axis_ptz_ros2.ptz.backend import PtzReading
from axis_ptz_ros2.ptz.command_slot import Outcome, Ticket
from axis_ptz_ros2.ptz.control import Target
from axis_ptz_ros2.ptz.state import StateSample

#: How a new target follows from the accepted one and the measured pose (raises ValueError if it cannot).
Spec = Callable[[Target | None, PtzReading | None], Target | None]


def then(first: Spec, second: Spec) -> Spec:
    """``first``, then ``second`` on its result."""
    return lambda base, r: second(first(base, r), r)


def const(target: Target | None) -> Spec:
    """A spec whose target is ``target`` whatever came before."""
    return lambda _base, _r: target


def axis_value(value: float, name: str) -> float | None:
    """A command field where NaN means "keep this axis". ±inf is refused (ValueError), never read as "keep"."""
    v = float(value)
    if math.isnan(v):
        return None
    if math.isinf(v):
        raise ValueError(f"{name} is {'+' if v > 0 else '-'}inf: give a finite value, or NaN to keep the axis")
    return v


def rate_value(value: float, name: str) -> float:
    """A velocity field: must be finite (NaN and ±inf are refused, never read as a stop)."""
    v = float(value)
    if not math.isfinite(v):
        raise ValueError(f"{name} is {v}: a velocity must be finite (0 = no motion on that axis)")
    return v


@dataclass(eq=False)
class Order:
    """One submitted command. ``target`` is the provisional target until the camera accepts the order, then
    the target that was sent (None for a move whose end pose is unknown)."""

    label: str
    gen: int = 0
    ticket: Ticket | None = None
    reason: str = ""  # why it was refused (then ticket is None)
    target: Target | None = None
    preset: str = ""  # for a preset goto: its name (its pose is learned on arrival)
    accepted_mono: float = 0.0  # when the camera accepted it (monotonic s)
    zooming: bool = False  # a velocity order with a zoom rate

    @property
    def refused(self) -> bool:
        """Refused before it reached the camera."""
        return self.ticket is None


@dataclass(frozen=True, slots=True)
class Progress:
    """One step of following an order (:func:`~axis_ptz_ros2.ptz.arrival.track`): the newest sample, the remaining
    error and, once ``done``, the outcome."""

    sample: StateSample | None
    target: Target | None
    done: bool = False
    success: bool = False
    message: str = ""
    error: tuple[float, float, float] = (math.nan, math.nan, math.nan)  # pan rad, tilt rad, zoom units


def remaining_error(target: Target | None, r: PtzReading | None) -> tuple[float, float, float]:
    """Target minus reading per axis (NaN where the axis is not commanded or nothing is known)."""
    if target is None or r is None:
        return (math.nan, math.nan, math.nan)
    return (
        wrap_angle(target.pan - r.pan) if target.pan is not None else math.nan,
        target.tilt - r.tilt if target.tilt is not None else math.nan,
        target.zoom - r.zoom if target.zoom is not None else math.nan,
    )


def describe(r: PtzReading) -> str:
    """A pose for messages (degrees for people, zoom units)."""
    return f"pan {math.degrees(r.pan):.3f} deg, tilt {math.degrees(r.tilt):.3f} deg, zoom {r.zoom:g}"


@dataclass(frozen=True, slots=True)
class Tolerances:
    """Arrival tolerances and the velocity timeout: a frozen snapshot of the node's dynamic parameters (replaced
    as a whole when one changes). The defaults here are the parameters' defaults."""

    pan_tilt_rad: float = 0.002
    zoom_units: float = 2.0
    velocity_timeout_s: float = 0.5


@dataclass
class CommanderStats:
    """Counters for diagnostics."""

    refused: int = 0
    refused_at_send: int = 0
    halted_after_failure: int = 0
    last_refusal: str = ""
    presets_known: list[str] = field(default_factory=list)


def wait_accepted(ticket: Ticket | None, reason: str, timeout_s: float) -> tuple[bool, str]:
    """Whether the camera accepted a command (``reason``: why it was refused when ``ticket`` is None)."""
    if ticket is None:
        return False, reason
    if not ticket.wait(max(0.0, timeout_s)):
        return False, "timed out waiting for the camera to accept the command"
    if ticket.outcome is Outcome.SENT:
        return True, "sent"
    if ticket.outcome is Outcome.SUPERSEDED:
        return False, "superseded by a newer command before it was sent"
    return False, f"camera error: {ticket.error}" if ticket.error else str(ticket.outcome)
