"""From request fields to orders (ROS-free): what the node's topics, services and goals ask, checked.

The node hands over the fields of its messages as plain numbers; every method returns an
:class:`~axis_ptz_ros2.ptz.orders.Order`, refused with the reason when the request is invalid. Conventions:
NaN = keep that axis (or: not given), ±inf refused; an image size of 0 = the stream's size; a pixel must lie
inside the image; zoom set-points derived from the pose are clamped to the head's range.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from enum import IntEnum

from axis_ptz_ros2.geometry import PtzKinematics
from axis_ptz_ros2.optics import ZoomModel
from axis_ptz_ros2.ptz.backend import PtzLimitsRos
from axis_ptz_ros2.ptz.commander import Commander
from axis_ptz_ros2.ptz.control import area_zoom_command, look_at_target, pixel_center_target, zoom_target
from axis_ptz_ros2.ptz.orders import Order, axis_value
from axis_ptz_ros2.transforms import Transform
from axis_ptz_ros2.vapix.models import MAX_IMAGE_SIDE


class GoalKind(IntEnum):
    """The kinds of a ``ptz/move`` goal (the action's constants)."""

    ABSOLUTE = 0
    RELATIVE = 1
    ZOOM = 2
    LOOK_AT = 3
    HOME = 4
    PRESET = 5


@dataclass(frozen=True, slots=True)
class MoveGoal:
    """The fields of a ``ptz/move`` goal in plain numbers (see ``PtzMove.action``)."""

    kind: int
    command: tuple[float, float, float, float]  # pan, tilt, zoom, speed
    magnification: float
    hfov: float
    point: tuple[float, float, float]
    frame: str
    preset: str


def _unused_if_zero(v: float) -> float:
    return math.nan if v == 0.0 else v  # 0 is no valid zoom, magnification or field of view


def stream_size(width: int, height: int) -> tuple[int, int] | None:
    """A published stream size (``video/params``) the pixel commands follow; None when it is no usable size."""
    if 0 < width <= MAX_IMAGE_SIDE and 0 < height <= MAX_IMAGE_SIDE:
        return int(width), int(height)
    return None


class Requests:
    """Turns requests in ROS units into orders of one :class:`Commander`."""

    def __init__(
        self,
        cmd: Commander,
        zoom_model: ZoomModel,
        head: PtzKinematics,
        frames: tuple[str, str],
        T_parent_ptzbase: Transform,
        limits: Callable[[], PtzLimitsRos],
        image_size: Callable[[], tuple[int, int]],
    ) -> None:
        """``frames``: (PTZ base frame, mount parent frame) a look-at point may be given in;
        ``T_parent_ptzbase``: the mount; ``limits``: joint limits now; ``image_size``: the stream's size now."""
        self._cmd = cmd
        self._zoom = zoom_model
        self._head = head
        self._frames = frames
        self._mount = T_parent_ptzbase
        self._limits = limits
        self._image_size = image_size

    def size(self, width: int = 0, height: int = 0) -> tuple[int, int]:
        """``width``×``height``, each 0 replaced by the stream's; ValueError beyond a real image's size (a uint32
        field can carry 2^32 - 1: such a size is refused, never wrapped or carried on)."""
        if not (0 <= int(width) <= MAX_IMAGE_SIDE and 0 <= int(height) <= MAX_IMAGE_SIDE):
            raise ValueError(f"image size {width}x{height} outside 1..{MAX_IMAGE_SIDE} px per side (0 = the stream's)")
        w, h = self._image_size()
        return (int(width) or w), (int(height) or h)

    def move(self, label: str, pan: float, tilt: float, zoom: float, speed: float, *, relative: bool) -> Order:
        """An absolute or relative move (speed NaN or 0: the camera's default)."""
        try:
            p, t, z = axis_value(pan, "pan"), axis_value(tilt, "tilt"), axis_value(zoom, "zoom")
            s = axis_value(speed, "speed")
            if s is not None and not 0.0 <= s <= 1.0:
                raise ValueError(f"speed {s:g} outside 0..1 (a fraction of the maximum speed; 0 or NaN = the camera's)")
        except ValueError as err:
            return self._cmd.refuse(label, str(err))
        return self._cmd.move(label, p, t, z, relative=relative, speed=s or None)

    def center(self, u: float, v: float, width: int, height: int, zoom_delta: float) -> Order:
        """Bring pixel (u, v) to the image centre, optionally zooming by ``zoom_delta`` units."""
        try:
            w, h = self.size(width, height)
            pan, tilt, zoom = pixel_center_target(
                self._cmd.reading(), u, v, w, h, self._zoom, zoom_delta, self._limits()
            )
        except ValueError as err:
            return self._cmd.refuse("center", str(err))
        return self._cmd.move("center", pan, tilt, zoom)

    def area_zoom(self, box: tuple[float, float, float, float], width: int, height: int) -> Order:
        """Centre on the box ``(u_min, v_min, u_max, v_max)`` and zoom so it fills the view."""
        try:
            w, h = self.size(width, height)
            pan, tilt, zoom = area_zoom_command(self._cmd.reading(), box, w, h, self._zoom, self._limits())
        except ValueError as err:
            return self._cmd.refuse("area_zoom", str(err))
        return self._cmd.move("area_zoom", pan, tilt, zoom)

    def set_zoom(self, zoom: float, magnification: float, hfov: float) -> Order:
        """Zoom to exactly one of units, magnification or horizontal field of view (rad); the others NaN."""
        try:
            z, m = axis_value(zoom, "zoom"), axis_value(magnification, "magnification")
            units = zoom_target(self._zoom, z, m, axis_value(hfov, "hfov"))
        except ValueError as err:
            return self._cmd.refuse("set_zoom", str(err))
        return self._cmd.move("set_zoom", None, None, units)

    def look_at(self, point: Sequence[float], frame: str, zoom: float) -> Order:
        """Put ``point`` (in the PTZ base or the mount's parent frame; '' = PTZ base) on the optical axis."""
        try:
            z = axis_value(zoom, "zoom")
            pan, tilt = look_at_target(point, frame, *self._frames, self._mount, self._head)
        except ValueError as err:
            return self._cmd.refuse("look_at", str(err))
        return self._cmd.move("look_at", pan, tilt, z)

    def goal(self, g: MoveGoal) -> Order:
        """The order of a ``ptz/move`` goal (a zoom, magnification or field of view of 0 counts as not given)."""
        pan, tilt, zoom, speed = g.command
        if g.kind == GoalKind.ABSOLUTE:
            return self.move("move_absolute", pan, tilt, zoom, speed, relative=False)
        if g.kind == GoalKind.RELATIVE:
            return self.move("move_relative", pan, tilt, zoom, speed, relative=True)
        if g.kind == GoalKind.ZOOM:
            return self.set_zoom(*(_unused_if_zero(v) for v in (zoom, g.magnification, g.hfov)))
        if g.kind == GoalKind.LOOK_AT:
            return self.look_at(g.point, g.frame, _unused_if_zero(zoom))
        if g.kind == GoalKind.HOME:
            return self._cmd.home()
        if g.kind == GoalKind.PRESET:
            if not g.preset:
                return self._cmd.refuse("move_preset", "kind PRESET needs a preset name")
            return self._cmd.goto_preset(g.preset)
        return self._cmd.refuse("move", f"unknown goal kind {g.kind} (0..5: ABSOLUTE..PRESET)")
