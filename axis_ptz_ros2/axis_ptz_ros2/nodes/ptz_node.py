"""The PTZ node: commands, services, state, joint states and transforms of a pan-tilt-zoom head.

ROS glue only (parameters, topics, services, the ``ptz/move`` action, wiring) over the ROS-free
:mod:`axis_ptz_ros2.ptz` core: request fields become orders in :mod:`~axis_ptz_ros2.ptz.requests` (NaN/inf,
pixel and zoom clamps); every order goes through one :class:`~axis_ptz_ros2.ptz.commander.Commander` (targets
recorded on the camera's acceptance, velocity mode, presets, arrival, the drive-safe zoom cap); services and
goals follow it with :mod:`~axis_ptz_ros2.ptz.goals` (arrival, cancel and pre-emption policy); state comes from
:mod:`~axis_ptz_ros2.ptz.state_loop` and its health from :mod:`~axis_ptz_ros2.ptz.health`. The same
:class:`PtzNode` serves the Axis backend (default, built from parameters) and any other
:class:`~axis_ptz_ros2.ptz.backend.PtzBackend` passed as ``backend=``. This module holds the parameters, the
command topics and the wiring; the services and the ``ptz/move`` action are :mod:`~axis_ptz_ros2.nodes.ptz_services`,
the state, joint-state and transform publishing :mod:`~axis_ptz_ros2.nodes.ptz_publish`.

Threads: one command worker (:class:`~axis_ptz_ros2.ptz.command_slot.CommandSlot`, latest motion wins, at
most one request in flight) and the state loop's poll thread (its own connection, paced at ``state_rate``,
surviving camera errors and restarting after anything unexpected), both joined in :meth:`PtzNode.destroy_node`;
services run in their own callback group so they never block topic commands, action goals in a reentrant group.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PointStamped, Twist
from nav_msgs.msg import Odometry
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.node import Node

from axis_ptz_interfaces.msg import PixelTarget, PtzCommand, PtzVelocity, VideoParams
from axis_ptz_ros2.config import CameraModel, MountConfig, load_camera_model, load_mount
from axis_ptz_ros2.nodes.common import (
    COMMAND_QOS,
    CONNECTION_PARAMS,
    LATCHED_QOS,
    RELATIVE_QOS,
    ParamSpec,
    camera_config_from_params,
    diagnostic,
    field_spec,
    publisher,
)
from axis_ptz_ros2.nodes.live_params import LiveParams, Params
from axis_ptz_ros2.nodes.ptz_publish import PtzFrames, PtzStatePublisher
from axis_ptz_ros2.nodes.ptz_services import PtzServices, center_order, look_at_order, move_order
from axis_ptz_ros2.nodes.runner import run_nodes
from axis_ptz_ros2.ptz.backend import PtzBackend, PtzBackendError, PtzLimitsRos
from axis_ptz_ros2.ptz.command_slot import CommandSlot, Ticket
from axis_ptz_ros2.ptz.commander import Commander
from axis_ptz_ros2.ptz.control import JointOffsets, Target
from axis_ptz_ros2.ptz.drive_safe import DriveSafeCap, DriveSafeConfig, DriveSafeZoom
from axis_ptz_ros2.ptz.goals import Follower
from axis_ptz_ros2.ptz.health import Health, diagnostic_values, judge, stale_after, state_age
from axis_ptz_ros2.ptz.orders import Order, Tolerances
from axis_ptz_ros2.ptz.requests import Requests, stream_size
from axis_ptz_ros2.ptz.state import StatePoller, StateSample
from axis_ptz_ros2.ptz.state_loop import StateLoop

#: The frame and joint names (the virtual camera declares the same parameters with its own defaults).
FRAME_PARAMS: tuple[ParamSpec, ...] = (
    ParamSpec("frame_prefix", "", "prefix of every frame name (e.g. 'robot1/')", read_only=True),
    ParamSpec("base_frame", "", "mount parent frame ('' = the mount file's, base_link)", read_only=True),
    ParamSpec("ptz_base_frame", "", "PTZ base frame ('' = the mount file's, axis_ptz_base)", read_only=True),
    ParamSpec("optical_frame", "axis_ptz_optical_frame", "optical frame of the PTZ camera", read_only=True),
    ParamSpec("pan_joint", "axis_ptz_pan_joint", "JointState name of the pan joint", read_only=True),
    ParamSpec("tilt_joint", "axis_ptz_tilt_joint", "JointState name of the tilt joint", read_only=True),
)

PARAMS: tuple[ParamSpec, ...] = (
    *CONNECTION_PARAMS,
    ParamSpec("timeout", 5.0, "command request timeout", "s", float_range=(0.1, 60.0), read_only=True),
    ParamSpec("state_timeout", 1.0, "timeout of one state poll", "s", float_range=(0.05, 30.0), read_only=True),
    ParamSpec("camera_model", "", "camera-model YAML ('' = chosen by the camera's reported model, else "
              "config/generic.yaml with the camera's own optics)", read_only=True),
    ParamSpec("mount_file", "", "mount YAML base_link -> PTZ base ('' = config/mount.yaml)", read_only=True),
    ParamSpec("state_rate", 20.0, "state polling/publishing rate", "Hz", float_range=(0.1, 100.0), read_only=True),
    field_spec(Tolerances, "velocity_timeout_s", "stop a velocity command after this long without a new one", "s",
               name="velocity_timeout", float_range=(0.05, 10.0)),
    field_spec(Tolerances, "pan_tilt_rad", "pan/tilt distance counted as arrived", "rad", name="arrival_tolerance",
               float_range=(1e-5, 0.2)),
    field_spec(Tolerances, "zoom_units", "zoom distance counted as arrived", "zoom units", name="zoom_tolerance",
               float_range=(0.0, 1000.0)),
    ParamSpec("wait_timeout", 15.0, "default timeout of services with wait=true", "s", float_range=(0.1, 300.0)),
    ParamSpec("image_width", 704, "stream width for hfov/vfov and pixel commands until video/params tells "
              "one (always, with follow_video_params false)", "px", int_range=(1, 10000)),
    ParamSpec("image_height", 576, "stream height for hfov/vfov and pixel commands until video/params tells "
              "one (always, with follow_video_params false)", "px", int_range=(1, 10000)),
    ParamSpec("follow_video_params", True, "take the stream size from video/params when published (runtime "
              "state: the image_width/image_height parameters are not rewritten)"),
    *FRAME_PARAMS,
    ParamSpec("publish_tf", True, "the mount on /tf_static, the pan/tilt head on /tf (tf2_msgs)", read_only=True),
    ParamSpec("drive_topic", "", "drive-safe zoom: the robot's odometry or cmd_vel topic ('' = off)",
              read_only=True),
    ParamSpec("drive_topic_type", "odometry", "message type of drive_topic: nav_msgs/Odometry or "
              "geometry_msgs/Twist", choices=("odometry", "twist"), read_only=True),
    field_spec(DriveSafeConfig, "speed_mps", "drive-safe zoom: cap the zoom above this linear speed", "m/s",
               name="drive_speed_threshold", float_range=(0.0, 100.0)),
    field_spec(DriveSafeConfig, "turn_rps", "drive-safe zoom: cap the zoom above this turn rate", "rad/s",
               name="drive_turn_threshold", float_range=(0.0, 100.0)),
    field_spec(DriveSafeConfig, "zoom_cap", "drive-safe zoom: highest zoom while driving (thesis: above ~4000 "
               "unusable on cobblestones)", "VAPIX units", name="drive_zoom_cap", float_range=(1.0, 99999.0)),
    field_spec(DriveSafeConfig, "hold_s", "drive-safe zoom: restore the operator's zoom after the robot has been "
               "below both thresholds this long", "s", name="drive_hold_time", float_range=(0.0, 600.0)),
)  # fmt: skip
_DYNAMIC = frozenset(s.name for s in PARAMS if not s.read_only)  # live: the node follows a change at run time


def build_axis_backend(p: Params, model: CameraModel) -> PtzBackend:
    """The default backend: VAPIX over HTTP, configured from the node's parameters."""
    from axis_ptz_ros2.ptz.axis_backend import AxisBackend

    cfg = camera_config_from_params(p, timeout_s=float(p["timeout"]))
    return AxisBackend(cfg, model, state_timeout_s=float(p["state_timeout"]))


class PtzNode(Node):
    """Pan-tilt-zoom control and state (see the module docstring and the README tables)."""

    def _learn_model(self, p: Params) -> CameraModel:
        from axis_ptz_ros2.camera_models import learn_camera_model

        cfg = camera_config_from_params(p, timeout_s=float(p["timeout"]))
        model, profile, error = learn_camera_model(cfg, str(p["camera_model"]))
        if profile is not None:
            self.get_logger().info(profile.summary())
        else:
            self.get_logger().warning(f"cannot ask the camera what it is ({error}); camera model {model.name!r}")
        return model

    def __init__(
        self,
        *,
        backend: PtzBackend | None = None,
        model: CameraModel | None = None,
        mount: MountConfig | None = None,
        node_name: str = "axis_ptz",
        **kwargs: Any,
    ) -> None:
        """``backend``: a ready head (e.g. a virtual camera); default: the Axis backend from parameters.
        ``model``/``mount``: given directly instead of read from the ``camera_model``/``mount_file`` files."""
        super().__init__(node_name, **kwargs)
        self._live = LiveParams(self, PARAMS, on_change=self._on_params)  # applied only once every check passed
        p = self._live.params  # (the read-only ones are read once, here)
        self._video_size: tuple[int, int] | None = None  # the stream's size from video/params (runtime state)
        if model is None and backend is None:
            model = self._learn_model(p)  # from the camera (camera_models.discover), logged in one line
        self._model = model if model is not None else load_camera_model(p["camera_model"] or None)
        self._mount: MountConfig = mount if mount is not None else load_mount(p["mount_file"] or None)
        self._offsets = JointOffsets(self._mount.pan_offset, self._mount.tilt_offset)
        prefix = str(p["frame_prefix"])
        frames = PtzFrames(
            base=prefix + (p["base_frame"] or self._mount.parent_frame),
            ptz_base=prefix + (p["ptz_base_frame"] or self._mount.child_frame),
            optical=prefix + str(p["optical_frame"]),
            pan_joint=str(p["pan_joint"]),
            tilt_joint=str(p["tilt_joint"]),
        )

        self._backend: PtzBackend = backend if backend is not None else build_axis_backend(p, self._model)
        self._slot = CommandSlot(error_types=(PtzBackendError,), on_error=self._on_command_error)
        self._slot.start()
        period = 1.0 / float(p["state_rate"])
        self._poller = StatePoller(self._backend.read_state, period, max_backoff_s=max(2.0, period))
        self._cmd = Commander(
            self._backend, self._slot, self._poller, lambda: self.limits, self._live.config(Tolerances), self._offsets
        )
        self._req = Requests(
            self._cmd,
            self._model.zoom,
            self._model.head,
            (frames.ptz_base, frames.base),
            self._mount.transform,
            lambda: self.limits,
            self.image_size,
        )
        self._follower = Follower(self._cmd, self._poller, self._offsets, float(p["timeout"]))
        self._drive: DriveSafeCap | None = None
        if p["drive_topic"]:
            zoom = DriveSafeZoom(self._live.config(DriveSafeConfig))
            self._drive = DriveSafeCap(zoom, self._cmd, self.get_logger().info)

        # ptz/state, joint_states, ptz/transform, ptz/mount, /tf, /tf_static; /diagnostics
        drive = self._drive
        self._zoom_listeners: list[Callable[[float], None]] = []
        self._out = PtzStatePublisher(
            self,
            self._model,
            self._mount,
            self._offsets,
            frames,
            publish_tf=bool(p["publish_tf"]),
            cmd=self._cmd,
            limits=lambda: self.limits,
            image_size=self._req.size,
            drive_zoom_cap=lambda: drive.config.zoom_cap if drive is not None else math.nan,
        )
        self._diag_pub = publisher(self, DiagnosticArray, "/diagnostics", 10)

        # State: a thread of its own (ptz.state_loop); publishing from it is thread-safe in rclpy.
        self._loop = StateLoop(
            self._poller,
            self._backend.limits,
            self._on_sample,
            before_poll=self._drive.tick if self._drive is not None else None,
            on_crash=self._on_poll_crash,
            keep_running=self.context.ok,
        )
        self._loop.start()
        # Services never block topic commands; the velocity watchdog ticks only while a velocity command runs.
        self._cmd_group = g = MutuallyExclusiveCallbackGroup()
        watchdog = min(0.05, float(p["velocity_timeout"]) / 4.0)
        self._watchdog = self.create_timer(watchdog, self._on_watchdog, callback_group=g)
        self._watchdog.cancel()
        self._diag_timer = self.create_timer(1.0, self._publish_diagnostics, callback_group=g)

        self.create_subscription(PtzCommand, "ptz/cmd/absolute", self._on_absolute, COMMAND_QOS, callback_group=g)
        self.create_subscription(PtzCommand, "ptz/cmd/relative", self._on_relative, RELATIVE_QOS, callback_group=g)
        self.create_subscription(PtzVelocity, "ptz/cmd/velocity", self._on_velocity, COMMAND_QOS, callback_group=g)
        self.create_subscription(PixelTarget, "ptz/cmd/center", self._on_center, COMMAND_QOS, callback_group=g)
        self.create_subscription(PointStamped, "ptz/cmd/look_at", self._on_look_at, COMMAND_QOS, callback_group=g)
        self.create_subscription(VideoParams, "video/params", self._on_video_params, LATCHED_QOS, callback_group=g)
        if self._drive is not None:
            if p["drive_topic_type"] == "twist":
                self.create_subscription(Twist, p["drive_topic"], self._on_twist, 10, callback_group=g)
            else:
                self.create_subscription(Odometry, p["drive_topic"], self._on_odometry, 10, callback_group=g)

        self._ptz_services = PtzServices(
            self,
            self._req,
            self._cmd,
            self._follower,
            self._slot,
            self._backend,
            self._out.state_msg,
            lambda: self._live.params,
        )
        self.get_logger().info(
            f"PTZ node up: {self._backend!r}, state at {float(p['state_rate']):g} Hz, "
            f"{frames.base} -> {frames.ptz_base} -> {frames.optical}"
        )
        fixed = getattr(self._backend, "fixed_camera_reason", lambda: "")()
        if fixed:
            self.get_logger().error(f"this camera has no PTZ head: {fixed}; pan/tilt/zoom commands will not move it")

    # -- parameters -----------------------------------------------------------------------------------
    @property
    def live_params(self) -> LiveParams:
        """The node's parameters: ``.params`` is the snapshot in effect (what ``ros2 param get`` tells)."""
        return self._live

    def _on_params(self, names: frozenset[str]) -> None:
        """post-set (every check passed, the snapshot swapped): rebuild the settings the change touches."""
        if names & {s.name for s in PARAMS if s.config is Tolerances}:
            self._cmd.tol = self._live.config(Tolerances)
        if self._drive is not None and names & {s.name for s in PARAMS if s.config is DriveSafeConfig}:
            self._drive.reconfigure(self._live.config(DriveSafeConfig))

    def image_size(self) -> tuple[int, int]:
        """The stream size used for hfov/vfov and pixel commands: the one ``video/params`` told last (with
        ``follow_video_params``), else the ``image_width``/``image_height`` parameters."""
        p = self._live.params
        if p["follow_video_params"] and self._video_size is not None:
            return self._video_size
        return int(p["image_width"]), int(p["image_height"])

    def _on_video_params(self, msg: VideoParams) -> None:
        size = stream_size(msg.width, msg.height)
        if size is not None:
            self._video_size = size  # kept even while not followed: switching follow_video_params on uses it

    # -- state ----------------------------------------------------------------------------------------
    @property
    def limits(self) -> PtzLimitsRos:
        """Limits in joint coordinates (REP-103 radians, zoom units)."""
        return self._offsets.limits(self._loop.head_limits)

    @property
    def target(self) -> Target | None:
        """The target the camera last accepted (None after velocity commands or an unknown preset)."""
        return self._cmd.target

    @property
    def commander(self) -> Commander:
        """The command path (targets, velocity mode, presets, arrival)."""
        return self._cmd

    @property
    def slot(self) -> CommandSlot:
        """The command worker (statistics for diagnostics and benchmarks)."""
        return self._slot

    @property
    def poller(self) -> StatePoller:
        """The state poller (statistics)."""
        return self._poller

    def _on_poll_crash(self, reason: str) -> None:
        self.get_logger().error(
            f"state poll failed unexpectedly ({reason}); restarting the poller", throttle_duration_sec=5.0
        )

    def _on_sample(self, sample: StateSample) -> None:
        if self._cmd.on_sample(sample):
            self.get_logger().warn(
                "head settled away from the commanded target; relative moves now start from the measured pose"
            )
        self._out.publish(sample)
        for listener in self._zoom_listeners:
            listener(sample.reading.zoom)

    def add_zoom_listener(self, listener: Callable[[float], None]) -> None:
        """Call ``listener`` with every polled zoom (VAPIX units, the state poll's thread): a stream node in this
        process (``axis_camera``) takes its ``camera_info`` zoom from here rather than from ``ptz/state``."""
        self._zoom_listeners.append(listener)

    def health(self) -> Health:
        """The state polling's diagnostic verdict (age, staleness, camera answering)."""
        stale = stale_after(self._poller.period_s, float(self._live.params["state_timeout"]))
        return judge(self._poller.stats, state_age(self._poller.latest, time.time_ns()), stale)

    def _publish_diagnostics(self) -> None:
        if self._loop.ensure_running():
            self.get_logger().error("the state poll thread ended; starting a new one")
        h, loop, cmd = self.health(), self._loop, self._cmd
        values: dict[str, Any] = diagnostic_values(
            h, self._poller.stats, loop.restarts, loop.last_crash, self._slot.stats, cmd.stats
        )
        values["limits_source"] = getattr(self._backend, "limits_source", "backend")
        counters = getattr(self._backend, "auth_counters", None)
        if counters is not None:
            values.update(counters.as_dict())
        name, hw = f"{self.get_name()}: PTZ", repr(self._backend)
        self._diag_pub.publish(diagnostic(self, name, h.level, h.message, values, hardware_id=hw))

    # -- commands (ROS units; every path goes through the commander and ends in the command slot) --------
    def _on_command_error(self, ticket: Ticket, err: BaseException) -> None:
        self.get_logger().warn(f"PTZ command {ticket.label} failed: {err}", throttle_duration_sec=2.0)

    def _on_watchdog(self) -> None:
        if not self._cmd.velocity_active:
            self._watchdog.cancel()
        elif self._cmd.check_velocity_timeout():
            self._watchdog.cancel()
            self.get_logger().info("velocity command timed out: stopping", throttle_duration_sec=5.0)

    # -- topics ---------------------------------------------------------------------------------------
    def _log_refusal(self, what: str, order: Order) -> None:
        if order.refused:
            self.get_logger().warn(f"{what}: {order.reason}", throttle_duration_sec=2.0)

    def _on_absolute(self, msg: PtzCommand) -> None:
        self._log_refusal("ptz/cmd/absolute", move_order(self._req, "absolute", msg, relative=False))

    def _on_relative(self, msg: PtzCommand) -> None:
        self._log_refusal("ptz/cmd/relative", move_order(self._req, "relative", msg, relative=True))

    def _on_velocity(self, msg: PtzVelocity) -> None:
        order = self._cmd.velocity(msg.pan_rate, msg.tilt_rate, msg.zoom_rate)
        self._log_refusal("ptz/cmd/velocity", order)
        if not order.refused and self._cmd.velocity_active and self._watchdog.is_canceled():
            self._watchdog.reset()

    def _on_center(self, msg: PixelTarget) -> None:
        self._log_refusal("ptz/cmd/center", center_order(self._req, msg))

    def _on_look_at(self, msg: PointStamped) -> None:
        self._log_refusal("ptz/cmd/look_at", look_at_order(self._req, msg, math.nan))

    # -- drive-safe zoom ------------------------------------------------------------------------------
    def _on_odometry(self, msg: Odometry) -> None:
        self._on_twist(msg.twist.twist)

    def _on_twist(self, msg: Twist) -> None:
        if self._drive is not None:
            self._drive.on_speed(math.hypot(msg.linear.x, msg.linear.y), msg.angular.z)

    # ------------------------------------------------------------------------------------------------
    def destroy_node(self) -> None:
        """Stop a running velocity command (best effort), join the command worker, close the backend."""
        if self._cmd.velocity_active:
            order = self._cmd.stop()
            if order.ticket is not None:
                order.ticket.wait(1.0)
        self._loop.stop(timeout_s=float(self._live.params["state_timeout"]) + 1.0)
        self._slot.stop(timeout=float(self._live.params["timeout"]) + 1.0)
        self._backend.close()
        self._ptz_services.destroy()
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """``axis_ptz``: the PTZ node on its own."""
    return run_nodes([PtzNode], args)


if __name__ == "__main__":
    raise SystemExit(main())
