"""The web console's interface to the ROS side (ROS-free): :class:`ConsoleBackend` and :class:`CommandResult`.

The HTTP side (:mod:`.server`, :mod:`.handler`) calls the backend; the ``axis_web_console`` node implements it
(:mod:`.view` builds its answers). Neither side imports the other: both import this module.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol

from axis_ptz_ros2.web.h264relay import H264Slot
from axis_ptz_ros2.web.relay import FrameSlot


@dataclass
class CommandResult:
    """Outcome of an operator command: HTTP status, ``ok`` and a human-readable message (+ extra fields)."""

    ok: bool
    message: str
    status: int = 200
    extra: dict[str, Any] = field(default_factory=dict)

    def body(self) -> dict[str, Any]:
        """The JSON answer ``{ok, message, ...}``."""
        return {"ok": self.ok, "message": self.message, **self.extra}


class ConsoleBackend(Protocol):
    """What the HTTP side needs from the ROS side."""

    def slot(self, name: str) -> FrameSlot | None:
        """The frame slot of stream ``name`` (``ptz``, ``panorama``, ``overlay``; ``still``: the last still), or None if
        not served."""

    def h264_slot(self, name: str) -> H264Slot | None:
        """The H.264 relay of stream ``name`` (only ``ptz``), or None if not served."""

    def state(self) -> dict[str, Any]:
        """Everything the page shows (JSON-serialisable)."""

    def keymap(self) -> dict[str, Any]:
        """The keyboard teleop key map as JSON (one table drives the terminal teleop and the page)."""

    def command(self, name: str, body: dict[str, Any]) -> CommandResult:
        """Run one of :data:`.api.COMMANDS` (may raise :class:`.api.BadRequest`); must return within a bounded
        time."""
