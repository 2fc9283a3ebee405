"""``axis_joy_teleop``: drive the PTZ head with a joystick (``sensor_msgs/Joy``, e.g. from the ``joy`` package).

A thin node over the pure :mod:`axis_ptz_ros2.teleop.joy` mapping: subscribes ``joy``, publishes
``ptz/cmd/velocity`` (repeated at ``rate`` while the dead-man button is held, one explicit stop when motion
ends or Joy messages stop for ``joy_timeout``), calls ``ptz/home`` and ``ptz/preset`` (goto) on button
presses. Every map parameter can be changed at run time; a map that does not make sense (two actions on one
button, a dead-man button that is also an action, preset buttons without names…) is refused with the reason,
at start-up (exit code 2) and on ``set_parameters``.

    axis_joy_teleop --ros-args --params-file config/joy_gamepad.params.yaml -r __ns:=/robot
"""

from __future__ import annotations

import dataclasses
import signal
import sys
import threading
import time
from collections.abc import Mapping
from types import FrameType
from typing import Any

import rclpy
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import Joy
from std_srvs.srv import Trigger

from axis_ptz_interfaces.msg import PtzVelocity
from axis_ptz_interfaces.srv import Preset
from axis_ptz_ros2.nodes.common import COMMAND_QOS, ParamSpec, field_spec, publisher, snapshot
from axis_ptz_ros2.nodes.live_params import LiveParams, Params
from axis_ptz_ros2.nodes.runner import close_own_loop
from axis_ptz_ros2.teleop.joy import (
    MAX_PAN_TILT_SPEED,
    MAX_ZOOM_SPEED,
    Command,
    GotoPreset,
    Home,
    JoyMap,
    JoyTeleop,
    Stop,
    Velocity,
)

#: Joy axis and button indices (-1 = none)
_INDEX = (-1, 63)
#: rad/s, either sign (JoyMap refuses more)
_PAN_TILT_SPEED = (-MAX_PAN_TILT_SPEED, MAX_PAN_TILT_SPEED)


def _map(field: str, description: str, unit: str = "", **kw: Any) -> ParamSpec:
    """A map parameter: fills ``JoyMap.<field>``, its default from there."""
    return field_spec(JoyMap, field, description, unit, **kw)


def _map_list(field: str, description: str) -> ParamSpec:
    """A list-valued map parameter: ``JoyMap``'s tuple default as the list a parameter file writes."""
    spec = _map(field, description)
    return dataclasses.replace(spec, default=list(spec.default))


PARAMS: tuple[ParamSpec, ...] = (
    # -- the map (live): defaults from JoyMap --
    _map("pan_axis", "Joy axis for pan (left = positive = turn left; -1 = none)", int_range=_INDEX),
    _map("tilt_axis", "Joy axis for tilt (up = positive = tilt up; -1 = none)", int_range=_INDEX),
    _map("zoom_axis", "Joy axis for zoom (up = positive = zoom in; -1 = none)", int_range=_INDEX),
    _map("pan_speed", "pan rate at full deflection (negative inverts)", "rad/s", float_range=_PAN_TILT_SPEED),
    _map("tilt_speed", "tilt rate at full deflection (negative inverts)", "rad/s", float_range=_PAN_TILT_SPEED),
    _map(
        "zoom_speed",
        "zoom rate at full deflection, fraction of the camera's",
        "1",
        float_range=(-MAX_ZOOM_SPEED, MAX_ZOOM_SPEED),
    ),
    _map("deadzone", "stick deflection ignored around the centre", "1", float_range=(0.0, 0.95)),
    _map("deadman_button", "button that must be held for any motion (-1 = none: simulators only)", int_range=_INDEX),
    _map("home_button", "button: home (pan 0, tilt 0, zoom 1) (-1 = none)", int_range=_INDEX),
    _map("zoom_in_button", "button: zoom in at zoom_speed while held (-1 = none)", int_range=_INDEX),
    _map("zoom_out_button", "button: zoom out at zoom_speed while held (-1 = none)", int_range=_INDEX),
    _map_list("preset_buttons", "buttons that go to the presets named in preset_names (same order)"),
    _map_list("preset_names", "camera preset names for preset_buttons"),
    _map("timeout", "stop when no Joy message came for this long", "s", name="joy_timeout", float_range=(0.05, 10.0)),
    # -- the node (read-only) --
    ParamSpec("rate", 10.0, "velocity repeat rate while moving", "Hz", float_range=(1.0, 100.0), read_only=True),
)


def joy_map_from_params(p: Mapping[str, Any]) -> JoyMap:
    """A :class:`JoyMap` from parameter values (a :func:`snapshot` of the specs that fill it, the two lists as
    tuples); ValueError with every reason when it is not usable."""
    try:
        buttons = tuple(int(b) for b in p["preset_buttons"])
    except (TypeError, ValueError) as err:
        raise ValueError(f"preset_buttons must be a list of integers: {err}") from None
    names = tuple(str(n) for n in p["preset_names"])
    return snapshot(JoyMap, PARAMS, {**p, "preset_buttons": buttons, "preset_names": names})


class JoyTeleopNode(Node):
    """Joy → PTZ commands (see the module docstring and the README table)."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("axis_joy_teleop", **kwargs)
        self._live = LiveParams(self, PARAMS, validate=self._check_params, on_change=self._apply_params)
        self._lock = threading.Lock()
        self._teleop = JoyTeleop(joy_map_from_params(self._live.params))  # ValueError: refused at start-up
        self._warned = 0
        self._vel_pub = publisher(self, PtzVelocity, "ptz/cmd/velocity", COMMAND_QOS)
        self._home = self.create_client(Trigger, "ptz/home")
        self._preset = self.create_client(Preset, "ptz/preset")
        self.create_subscription(Joy, "joy", self._on_joy, 10)
        self._timer = self.create_timer(1.0 / float(self._live.params["rate"]), self._on_tick)
        m = self._teleop.joy_map
        self.get_logger().info(
            f"joystick teleop up: axes pan {m.pan_axis} tilt {m.tilt_axis} zoom {m.zoom_axis}, "
            f"dead-man button {m.deadman_button}, home {m.home_button}, presets "
            f"{dict(zip(m.preset_buttons, m.preset_names, strict=True))}, stop after {m.timeout:g} s without Joy"
        )

    # ---- parameters -------------------------------------------------------------------------------
    @property
    def live_params(self) -> LiveParams:
        """The node's parameters: ``.params`` is the snapshot in effect (what ``ros2 param get`` tells)."""
        return self._live

    @staticmethod
    def _check_params(candidate: Params, _names: frozenset[str]) -> str | None:
        """on-set: the whole candidate map must be usable (e.g. as many preset names as buttons)."""
        try:
            joy_map_from_params(candidate)
        except ValueError as err:
            return str(err)
        return None

    def _apply_params(self, _names: frozenset[str]) -> None:
        with self._lock:
            self._teleop.joy_map = joy_map_from_params(self._live.params)
            self._teleop.warnings.clear()
            self._warned = 0

    @property
    def teleop(self) -> JoyTeleop:
        """The mapping state (for tests and diagnostics)."""
        return self._teleop

    # ---- inputs -----------------------------------------------------------------------------------
    def _on_joy(self, msg: Joy) -> None:
        with self._lock:
            commands = self._teleop.on_joy(list(msg.axes), list(msg.buttons), time.monotonic())
            warnings = self._teleop.warnings[self._warned :]
            self._warned = len(self._teleop.warnings)
        for w in warnings:
            self.get_logger().warn(w)
        for c in commands:
            self._send(c)

    def _on_tick(self) -> None:
        with self._lock:
            commands = self._teleop.tick(time.monotonic())
        for c in commands:
            self._send(c)

    # ---- outputs ----------------------------------------------------------------------------------
    def _send(self, c: Command) -> None:
        if isinstance(c, Velocity):
            self._vel_pub.publish(PtzVelocity(pan_rate=c.pan_rate, tilt_rate=c.tilt_rate, zoom_rate=c.zoom_rate))
        elif isinstance(c, Stop):
            self._vel_pub.publish(PtzVelocity(pan_rate=0.0, tilt_rate=0.0, zoom_rate=0.0))
            self.get_logger().info(f"stop: {c.reason}")
        elif isinstance(c, Home):
            self._call(self._home, Trigger.Request(), "ptz/home")
        elif isinstance(c, GotoPreset):
            req = Preset.Request(action="goto", name=c.name, wait=False, timeout_s=0.0)
            self._call(self._preset, req, f"ptz/preset goto {c.name!r}")

    def _call(self, client: Any, request: Any, what: str) -> None:
        if not client.service_is_ready():
            self.get_logger().warn(f"{what}: service not available (is the PTZ node running?)")
            return
        fut = client.call_async(request)

        def done(f: Any) -> None:
            try:
                r = f.result()
            except Exception as err:  # noqa: BLE001 - a failed call is reported, never raised into the executor
                self.get_logger().warn(f"{what} failed: {err}")
                return
            if r is not None and not r.success:
                self.get_logger().warn(f"{what} refused: {r.message}")

        fut.add_done_callback(done)

    def stop_motion(self, timeout_s: float = 1.0) -> bool:
        """Send a stop if we started motion, and wait until subscribers acknowledged it; True if one was sent."""
        with self._lock:
            moving = self._teleop.moving
            self._teleop = JoyTeleop(self._teleop.joy_map)  # forget the sticks: nothing repeats after this
        if not moving:
            return False
        self._vel_pub.publish(PtzVelocity(pan_rate=0.0, tilt_rate=0.0, zoom_rate=0.0))
        self._vel_pub.wait_for_all_acked(Duration(seconds=timeout_s))
        return True


def _interrupt(signum: int, frame: FrameType | None) -> None:
    # the first Ctrl-C / SIGTERM stops us; a second one (a process group gets one each from launch and the
    # terminal) must not cut the head's stop short or kill the clean-up: ignore both from now on
    for s in (signal.SIGINT, signal.SIGTERM):
        signal.signal(s, signal.SIG_IGN)
    raise KeyboardInterrupt


def main(args: list[str] | None = None) -> int:
    """Run the joystick teleop until Ctrl-C / SIGTERM, then stop the head if it was moving because of us.

    rclpy's own signal handler is off: it would shut the context down before we could send the stop."""
    rclpy.init(args=list(args) if args is not None else sys.argv, signal_handler_options=SignalHandlerOptions.NO)
    old = {s: signal.signal(s, _interrupt) for s in (signal.SIGINT, signal.SIGTERM)}
    executor = SingleThreadedExecutor()
    node: JoyTeleopNode | None = None
    code = 0
    try:
        node = JoyTeleopNode()
        executor.add_node(node)
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except ValueError as err:  # a parameter (file) that makes no sense: say why, exit non-zero
        print(f"error: {err}", file=sys.stderr)  # noqa: T201
        code = 2
    finally:
        for s in old:  # not the old handlers: Python's would turn a late second signal into a traceback
            signal.signal(s, signal.SIG_IGN)
        try:
            if node is not None and node.stop_motion():
                node.get_logger().info("stopped the head on exit")
        finally:
            close_own_loop(executor, node)
    return code


if __name__ == "__main__":
    raise SystemExit(main())
