"""The PTZ node: commands, services, state, joint states and transforms of a pan-tilt-zoom head.

A thin ROS layer over the ROS-free :mod:`axis_ptz_ros2.ptz` core. Every ROS-side decision (targets, relative
accumulation, limits, pointing maths in REP-103 radians) lives here or in :mod:`axis_ptz_ros2.ptz.control`, so
the same :class:`PtzNode` serves the Axis backend (default, built from parameters) and any other
:class:`~axis_ptz_ros2.ptz.backend.PtzBackend` passed as ``backend=``.

Threads: one command worker (:class:`~axis_ptz_ros2.ptz.command_slot.CommandSlot`, latest motion wins, at
most one request in flight) owned by the node and joined in :meth:`PtzNode.destroy_node`; state is polled by a
thread of its own over a separate connection (paced at ``state_rate``, never ending on camera errors), services
run in their own callback group so they never block topic commands.
"""

from __future__ import annotations

import contextlib
import math
import threading
import time
from collections.abc import Callable
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PointStamped, TransformStamped
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger

from axis_ptz_interfaces.msg import PixelTarget, PtzCommand, PtzState, PtzVelocity, VideoParams
from axis_ptz_interfaces.srv import AreaZoom, CenterOnPixel, ListPresets, LookAt, MovePtz, Preset, SetZoom
from axis_ptz_ros2.config import CameraModel, MountConfig, load_camera_model, load_mount
from axis_ptz_ros2.nodes.common import (
    COMMAND_QOS,
    CONNECTION_PARAMS,
    LATCHED_QOS,
    STREAM_QOS,
    ParamSpec,
    camera_config_from_params,
    check_params,
    declare_params,
    diagnostic,
    make_tf_broadcasters,
    run_nodes,
    stamp_from_ns,
    transform_msg,
)
from axis_ptz_ros2.ptz.backend import PtzBackend, PtzBackendError, PtzLimitsRos, PtzReading
from axis_ptz_ros2.ptz.command_slot import CommandSlot, Outcome, Ticket
from axis_ptz_ros2.ptz.control import (
    JointOffsets,
    Target,
    area_zoom_target,
    center_target,
    finite_or_none,
    look_at_target,
    merge_target,
    normalize_target,
    zoom_target,
)
from axis_ptz_ros2.ptz.state import StatePoller, StateSample

PARAMS: tuple[ParamSpec, ...] = (
    *CONNECTION_PARAMS,
    ParamSpec("timeout", 5.0, "command request timeout", "s", float_range=(0.1, 60.0), read_only=True),
    ParamSpec("state_timeout", 1.0, "timeout of one state poll", "s", float_range=(0.05, 30.0), read_only=True),
    ParamSpec(
        "camera_model",
        "",
        "camera-model YAML ('' = chosen by the camera's reported model, else config/generic.yaml with the "
        "camera's own optics)",
        read_only=True,
    ),
    ParamSpec("mount_file", "", "mount YAML base_link -> PTZ base ('' = config/mount.yaml)", read_only=True),
    ParamSpec("state_rate", 20.0, "state polling/publishing rate", "Hz", float_range=(0.1, 100.0), read_only=True),
    ParamSpec(
        "velocity_timeout",
        0.5,
        "stop a velocity command after this long without a new one",
        "s",
        float_range=(0.05, 10.0),
    ),
    ParamSpec("arrival_tolerance", 0.002, "pan/tilt distance counted as arrived", "rad", float_range=(1e-5, 0.2)),
    ParamSpec("zoom_tolerance", 2.0, "zoom distance counted as arrived", "zoom units", float_range=(0.0, 1000.0)),
    ParamSpec("wait_timeout", 15.0, "default timeout of services with wait=true", "s", float_range=(0.1, 300.0)),
    ParamSpec("image_width", 704, "stream width for hfov/vfov and pixel commands", "px", int_range=(1, 10000)),
    ParamSpec("image_height", 576, "stream height for hfov/vfov and pixel commands", "px", int_range=(1, 10000)),
    ParamSpec("follow_video_params", True, "take the stream size from video/params when published"),
    ParamSpec("frame_prefix", "", "prefix of every frame name (e.g. 'robot1/')", read_only=True),
    ParamSpec("base_frame", "", "mount parent frame ('' = the mount file's, base_link)", read_only=True),
    ParamSpec("ptz_base_frame", "", "PTZ base frame ('' = the mount file's, axis_ptz_base)", read_only=True),
    ParamSpec("optical_frame", "axis_ptz_optical_frame", "optical frame of the PTZ camera", read_only=True),
    ParamSpec("pan_joint", "axis_ptz_pan_joint", "JointState name of the pan joint", read_only=True),
    ParamSpec("tilt_joint", "axis_ptz_tilt_joint", "JointState name of the tilt joint", read_only=True),
    ParamSpec("publish_tf", True, "also broadcast /tf and /tf_static when tf2_ros is importable", read_only=True),
)
_SPECS = {s.name: s for s in PARAMS}
# DiagnosticStatus levels as ints (the message constants are bytes; nodes.common.diagnostic takes an int)
DIAG_OK, DIAG_WARN, DIAG_ERROR, DIAG_STALE = 0, 1, 2, 3
_DYNAMIC = (
    "velocity_timeout",
    "arrival_tolerance",
    "zoom_tolerance",
    "wait_timeout",
    "image_width",
    "image_height",
    "follow_video_params",
)


def build_axis_backend(p: dict[str, Any], model: CameraModel) -> PtzBackend:
    """The default backend: VAPIX over HTTP, configured from the node's parameters."""
    from axis_ptz_ros2.ptz.axis_backend import AxisBackend

    cfg = camera_config_from_params(p, timeout_s=float(p["timeout"]))
    return AxisBackend(cfg, model, state_timeout_s=float(p["state_timeout"]))


class PtzNode(Node):
    """Pan-tilt-zoom control and state (see the module docstring and the README tables)."""

    def _learn_model(self, p: dict[str, Any]) -> CameraModel:
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
        self._p = declare_params(self, PARAMS)
        self.add_on_set_parameters_callback(lambda params: check_params(_SPECS, params))
        self.add_post_set_parameters_callback(self._post_set_params)  # applied only once every check passed
        p = self._p
        if model is None and backend is None:
            model = self._learn_model(p)  # from the camera (camera_models.discover), logged in one line
        self._model = model if model is not None else load_camera_model(p["camera_model"] or None)
        self._mount: MountConfig = mount if mount is not None else load_mount(p["mount_file"] or None)
        self._offsets = JointOffsets(self._mount.pan_offset, self._mount.tilt_offset)
        prefix = str(p["frame_prefix"])
        self._base_frame = prefix + (p["base_frame"] or self._mount.parent_frame)
        self._ptz_base_frame = prefix + (p["ptz_base_frame"] or self._mount.child_frame)
        self._optical_frame = prefix + str(p["optical_frame"])
        self._joint_names = [str(p["pan_joint"]), str(p["tilt_joint"])]

        self._backend: PtzBackend = backend if backend is not None else build_axis_backend(p, self._model)
        self._lock = threading.RLock()  # target, velocity and limits bookkeeping
        self._target: Target | None = None
        self._velocity_active = False
        self._last_velocity = 0.0
        self._last_cmd_mono = 0.0
        self._refused = 0
        self._still_polls = 0
        self._head_limits: PtzLimitsRos = self._backend.limits()
        self._cmd_errors_logged = 0

        self._slot = CommandSlot(error_types=(PtzBackendError,), on_error=self._on_command_error)
        self._slot.start()
        period = 1.0 / float(p["state_rate"])
        self._poller = StatePoller(self._backend.read_state, period, max_backoff_s=max(2.0, period))

        # Publishers.
        self._state_pub = self.create_publisher(PtzState, "ptz/state", STREAM_QOS)
        self._joint_pub = self.create_publisher(JointState, "joint_states", STREAM_QOS)
        self._tf_pub = self.create_publisher(TransformStamped, "ptz/transform", STREAM_QOS)
        self._mount_pub = self.create_publisher(TransformStamped, "ptz/mount", LATCHED_QOS)
        self._diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self._tf, self._tf_static = make_tf_broadcasters(self) if p["publish_tf"] else (None, None)
        mount_msg = transform_msg(
            self._mount.transform, self._base_frame, self._ptz_base_frame, stamp_from_ns(time.time_ns())
        )
        self._mount_pub.publish(mount_msg)
        if self._tf_static is not None:
            self._tf_static.sendTransform(mount_msg)

        # Callback groups: polling never waits behind a service, services never block topic commands.
        self._srv_group = MutuallyExclusiveCallbackGroup()
        self._cmd_group = MutuallyExclusiveCallbackGroup()
        # State polling paces itself in one thread (stop event, joined in destroy_node) rather than an
        # executor timer: an rclpy executor wake-up costs ~2 ms of CPU, twice per tick, which alone would use
        # up the 5 %-of-a-core budget at 20 Hz. Publishing from this thread is thread-safe in rclpy.
        self._stop = threading.Event()
        self._poll_thread = threading.Thread(target=self._poll_loop, name="ptz-state", daemon=True)
        self._poll_thread.start()
        # The velocity watchdog ticks only while a velocity command is active (no idle wake-ups).
        watchdog = min(0.05, float(p["velocity_timeout"]) / 4.0)
        self._watchdog = self.create_timer(watchdog, self._on_watchdog, callback_group=self._cmd_group)
        self._watchdog.cancel()
        self._diag_timer = self.create_timer(1.0, self._publish_diagnostics, callback_group=self._cmd_group)

        g = self._cmd_group
        self.create_subscription(PtzCommand, "ptz/cmd/absolute", self._on_absolute, COMMAND_QOS, callback_group=g)
        self.create_subscription(PtzCommand, "ptz/cmd/relative", self._on_relative, COMMAND_QOS, callback_group=g)
        self.create_subscription(PtzVelocity, "ptz/cmd/velocity", self._on_velocity, COMMAND_QOS, callback_group=g)
        self.create_subscription(PixelTarget, "ptz/cmd/center", self._on_center, COMMAND_QOS, callback_group=g)
        self.create_subscription(PointStamped, "ptz/cmd/look_at", self._on_look_at, COMMAND_QOS, callback_group=g)
        self.create_subscription(VideoParams, "video/params", self._on_video_params, LATCHED_QOS, callback_group=g)

        s = self._srv_group
        self.create_service(MovePtz, "ptz/move_absolute", self._srv_absolute, callback_group=s)
        self.create_service(MovePtz, "ptz/move_relative", self._srv_relative, callback_group=s)
        self.create_service(CenterOnPixel, "ptz/center", self._srv_center, callback_group=s)
        self.create_service(AreaZoom, "ptz/area_zoom", self._srv_area_zoom, callback_group=s)
        self.create_service(SetZoom, "ptz/set_zoom", self._srv_set_zoom, callback_group=s)
        self.create_service(LookAt, "ptz/look_at", self._srv_look_at, callback_group=s)
        self.create_service(Trigger, "ptz/home", self._srv_home, callback_group=s)
        self.create_service(Preset, "ptz/preset", self._srv_preset, callback_group=s)
        self.create_service(ListPresets, "ptz/list_presets", self._srv_list_presets, callback_group=s)
        self.get_logger().info(
            f"PTZ node up: {self._backend!r}, state at {float(p['state_rate']):g} Hz, "
            f"{self._base_frame} -> {self._ptz_base_frame} -> {self._optical_frame}"
        )
        fixed = getattr(self._backend, "fixed_camera_reason", lambda: "")()
        if fixed:
            self.get_logger().error(f"this camera has no PTZ head: {fixed}; pan/tilt/zoom commands will not move it")

    # ------------------------------------------------------------------------------------------------
    # Parameters
    # ------------------------------------------------------------------------------------------------
    def _post_set_params(self, params: list[Parameter]) -> None:
        for prm in params:
            if prm.name in _DYNAMIC:
                self._p[prm.name] = prm.value

    def _image_size(self, width: int = 0, height: int = 0) -> tuple[int, int]:
        return (int(width) or int(self._p["image_width"])), (int(height) or int(self._p["image_height"]))

    def _on_video_params(self, msg: VideoParams) -> None:
        if self._p["follow_video_params"] and msg.width > 0 and msg.height > 0:
            self._p["image_width"], self._p["image_height"] = int(msg.width), int(msg.height)

    # ------------------------------------------------------------------------------------------------
    # State
    # ------------------------------------------------------------------------------------------------
    @property
    def limits(self) -> PtzLimitsRos:
        """Limits in joint coordinates (REP-103 radians, zoom units)."""
        return self._offsets.limits(self._head_limits)

    def _reading(self) -> PtzReading | None:
        s = self._poller.latest
        return None if s is None else self._offsets.from_head(s.reading)

    @property
    def target(self) -> Target | None:
        """The pose last commanded (None after velocity/home/preset commands)."""
        with self._lock:
            return self._target

    @property
    def slot(self) -> CommandSlot:
        """The command worker (statistics for diagnostics and benchmarks)."""
        return self._slot

    @property
    def poller(self) -> StatePoller:
        """The state poller (statistics)."""
        return self._poller

    def _poll_loop(self) -> None:
        """Poll at ``state_rate`` on a fixed schedule until destroy_node (the poller backs off by itself)."""
        period = self._poller.period_s
        next_t = time.monotonic()
        while not self._stop.is_set():
            try:
                self._on_poll()
            except Exception:  # noqa: BLE001 - only a shut-down context ends the loop; anything else is a bug
                if self._stop.is_set() or not self.context.ok():
                    return
                raise
            next_t += period
            now = time.monotonic()
            if next_t < now - period:  # fell behind (slow camera): do not burst to catch up
                next_t = now
            self._stop.wait(max(0.0, next_t - now))

    def _on_poll(self) -> None:
        sample = self._poller.poll()
        if self._poller.stats.ok % 100 == 1 or sample is None:
            with contextlib.suppress(PtzBackendError):  # camera limits once known; fallback retried
                self._head_limits = self._backend.limits()
        if sample is None:
            return
        self._track_target(sample)
        self._publish_state(sample)

    def _track_target(self, sample: StateSample) -> None:
        """Drop a target the head has evidently settled away from (reboot, another client moved it)."""
        with self._lock:
            if self._target is None:
                self._still_polls = 0
                return
            self._still_polls = 0 if sample.head_moving else self._still_polls + 1
            r = self._offsets.from_head(sample.reading)
            tol = float(self._p["arrival_tolerance"])
            if (
                self._still_polls >= 5
                and self._slot.idle
                and time.monotonic() - self._last_cmd_mono > 2.0
                and not self._target.reached(r, tol, float(self._p["zoom_tolerance"]))
            ):
                self.get_logger().warn(
                    "head settled away from the commanded target; relative moves now start from the measured pose"
                )
                self._target = None

    def _state_msg(self, sample: StateSample) -> PtzState:
        r = self._offsets.from_head(sample.reading)
        w, h = self._image_size()
        intr = self._model.zoom.intrinsics(r.zoom, w, h)
        lim = self.limits
        m = PtzState()
        m.header.stamp = stamp_from_ns(r.stamp_ns)
        m.header.frame_id = self._ptz_base_frame
        m.pan, m.tilt, m.zoom = float(r.pan), float(r.tilt), float(r.zoom)
        m.magnification = float(self._model.zoom.magnification(r.zoom))
        m.hfov, m.vfov = float(intr.hfov), float(intr.vfov)
        with self._lock:
            target, velocity = self._target, self._velocity_active
        reached = target is None or target.reached(
            r, float(self._p["arrival_tolerance"]), float(self._p["zoom_tolerance"])
        )
        m.moving = bool(sample.head_moving or velocity or not reached)
        m.pan_min, m.pan_max, m.tilt_min, m.tilt_max = lim.pan_min, lim.pan_max, lim.tilt_min, lim.tilt_max
        m.zoom_min, m.zoom_max = lim.zoom_min, lim.zoom_max
        return m

    def _publish_state(self, sample: StateSample) -> None:
        """ptz/state, joint_states, ptz/transform (each only when someone listens) and /tf when available."""
        r = self._offsets.from_head(sample.reading)
        stamp = stamp_from_ns(r.stamp_ns)
        if self._state_pub.get_subscription_count() > 0:
            self._state_pub.publish(self._state_msg(sample))
        if self._joint_pub.get_subscription_count() > 0:
            js = JointState()
            js.header.stamp = stamp
            js.name = list(self._joint_names)
            js.position = [float(r.pan), float(r.tilt)]
            js.velocity = [float(sample.pan_rate), float(sample.tilt_rate)]
            self._joint_pub.publish(js)
        want_tf = self._tf_pub.get_subscription_count() > 0
        if want_tf or self._tf is not None:
            T_opt = self._model.head.optical_in_ptz_base(r.pan, r.tilt)
            if want_tf:
                T = self._mount.transform @ T_opt
                self._tf_pub.publish(transform_msg(T, self._base_frame, self._optical_frame, stamp))
            if self._tf is not None:
                self._tf.sendTransform(transform_msg(T_opt, self._ptz_base_frame, self._optical_frame, stamp))

    def _publish_diagnostics(self) -> None:
        st, cs = self._poller.stats, self._slot.stats
        if st.ok == 0 and st.failed == 0:
            level, msg = DIAG_STALE, "no state poll yet"
        elif st.consecutive_failures >= 5:
            level, msg = DIAG_ERROR, f"camera not answering: {st.last_error}"
        elif st.consecutive_failures > 0:
            level, msg = DIAG_WARN, f"state poll failing: {st.last_error}"
        else:
            level, msg = DIAG_OK, "ok"
        values = {
            "state_rate_hz": st.rate_hz,
            "polls_ok": st.ok,
            "polls_failed": st.failed,
            "consecutive_failures": st.consecutive_failures,
            "last_poll_error": st.last_error,
            "last_poll_s": st.last_poll_s,
            "commands_submitted": cs.submitted,
            "commands_sent": cs.sent,
            "commands_failed": cs.failed,
            "commands_superseded": cs.superseded,
            "commands_refused": self._refused,
            "last_command_error": cs.last_error,
            "last_command_latency_s": cs.last_latency_s,
            "limits_source": getattr(self._backend, "limits_source", "backend"),
        }
        counters = getattr(self._backend, "auth_counters", None)
        if counters is not None:
            values.update(counters.as_dict())
        name = f"{self.get_name()}: PTZ"
        self._diag_pub.publish(diagnostic(self, name, level, msg, values, hardware_id=repr(self._backend)))

    # ------------------------------------------------------------------------------------------------
    # Commands (ROS units; every path ends in the command slot)
    # ------------------------------------------------------------------------------------------------
    def _on_command_error(self, ticket: Ticket, err: BaseException) -> None:
        self.get_logger().warn(f"PTZ command {ticket.label} failed: {err}", throttle_duration_sec=2.0)

    def _refuse(self, reason: str) -> tuple[None, None, str]:
        self._refused += 1
        return None, None, reason

    def _move(
        self,
        label: str,
        pan: float | None,
        tilt: float | None,
        zoom: float | None,
        *,
        relative: bool = False,
        speed: float | None = None,
    ) -> tuple[Ticket | None, Target | None, str]:
        """Merge into the target, check limits, submit. Returns (ticket, target, reason-if-refused)."""
        with self._lock:
            try:
                target = merge_target(self._target, self._reading(), pan, tilt, zoom, relative)
            except ValueError as err:
                return self._refuse(str(err))
            lim = self.limits
            target = normalize_target(target, lim)
            if target.zoom is not None:
                target = Target(target.pan, target.tilt, float(round(target.zoom)))
            if target.empty:
                return self._refuse("nothing to move: every axis is NaN")
            reason = lim.violation(target.pan, target.tilt, target.zoom)
            if reason is not None:
                return self._refuse(f"refused, not sent: {reason}")
            self._target = target
            self._velocity_active = False
            self._last_cmd_mono = time.monotonic()
            hp, ht = self._offsets.to_head(target.pan, target.tilt)
            backend, z = self._backend, target.zoom
            ticket = self._slot.submit(label, lambda: backend.move_to(hp, ht, z, speed))
        return ticket, target, ""

    def _untargeted(self, label: str, fn: Callable[[], None], supersedable: bool = True) -> Ticket:
        """Submit a command whose end pose the node does not know (home, preset, velocity)."""
        with self._lock:
            if supersedable:
                self._target = None
            self._last_cmd_mono = time.monotonic()
            return self._slot.submit(label, fn, supersedable=supersedable)

    def _velocity(self, pan_rate: float, tilt_rate: float, zoom_rate: float) -> Ticket:
        with self._lock:
            vals = [v if math.isfinite(v) else 0.0 for v in (pan_rate, tilt_rate, zoom_rate)]
            moving = any(v != 0.0 for v in vals)
            self._velocity_active = moving
            self._last_velocity = time.monotonic()
            if moving and self._watchdog.is_canceled():
                self._watchdog.reset()
            backend = self._backend
            label = "velocity" if moving else "stop"
            return self._untargeted(label, lambda: backend.velocity(vals[0], vals[1], max(-1.0, min(1.0, vals[2]))))

    def _on_watchdog(self) -> None:
        with self._lock:
            if not self._velocity_active:
                self._watchdog.cancel()
                return
            if time.monotonic() - self._last_velocity < float(self._p["velocity_timeout"]):
                return
            self._watchdog.cancel()
        self.get_logger().info("velocity command timed out: stopping", throttle_duration_sec=5.0)
        self._velocity(0.0, 0.0, 0.0)

    # -- pointing helpers -------------------------------------------------------------------------------
    def _center_pose(self, u: float, v: float, width: int, height: int) -> tuple[float, float] | str:
        r = self._reading()
        if r is None:
            return "the current pose is not known yet"
        w, h = self._image_size(width, height)
        if not (math.isfinite(u) and math.isfinite(v) and 0.0 <= u <= w - 1 and 0.0 <= v <= h - 1):
            return f"pixel ({u:g}, {v:g}) outside the {w}x{h} image"
        return center_target(r, u, v, w, h, self._model.zoom)

    def _center(self, t: PixelTarget) -> tuple[Ticket | None, Target | None, str]:
        pose = self._center_pose(t.u, t.v, t.image_width, t.image_height)
        if isinstance(pose, str):
            return self._refuse(pose)
        zoom = None
        if math.isfinite(t.zoom_delta) and t.zoom_delta != 0.0:
            r = self._reading()
            assert r is not None
            zoom = min(max(r.zoom + t.zoom_delta, self.limits.zoom_min), self.limits.zoom_max)
        return self._move("center", pose[0], pose[1], zoom)

    def _look_at(self, msg: PointStamped, zoom: float | None) -> tuple[Ticket | None, Target | None, str]:
        try:
            pan, tilt = look_at_target(
                (msg.point.x, msg.point.y, msg.point.z),
                msg.header.frame_id,
                self._ptz_base_frame,
                self._base_frame,
                self._mount.transform,
                self._model.head,
            )
        except ValueError as err:
            return self._refuse(str(err))
        return self._move("look_at", pan, tilt, zoom)

    # -- topics ---------------------------------------------------------------------------------------
    def _log_refusal(self, what: str, reason: str) -> None:
        if reason:
            self.get_logger().warn(f"{what}: {reason}", throttle_duration_sec=2.0)

    def _on_absolute(self, msg: PtzCommand) -> None:
        self._on_command("absolute", msg, relative=False)

    def _on_relative(self, msg: PtzCommand) -> None:
        self._on_command("relative", msg, relative=True)

    def _on_command(self, kind: str, c: PtzCommand, *, relative: bool) -> None:
        """ptz/cmd/absolute and ptz/cmd/relative: NaN = keep that axis; refusals are logged (throttled)."""
        _, _, reason = self._move(
            kind,
            finite_or_none(c.pan),
            finite_or_none(c.tilt),
            finite_or_none(c.zoom),
            relative=relative,
            speed=finite_or_none(c.speed),
        )
        self._log_refusal(f"ptz/cmd/{kind}", reason)

    def _on_velocity(self, msg: PtzVelocity) -> None:
        self._velocity(msg.pan_rate, msg.tilt_rate, msg.zoom_rate)

    def _on_center(self, msg: PixelTarget) -> None:
        self._log_refusal("ptz/cmd/center", self._center(msg)[2])

    def _on_look_at(self, msg: PointStamped) -> None:
        self._log_refusal("ptz/cmd/look_at", self._look_at(msg, None)[2])

    # -- services -------------------------------------------------------------------------------------
    def _timeout(self, timeout_s: float) -> float:
        return float(timeout_s) if math.isfinite(timeout_s) and timeout_s > 0.0 else float(self._p["wait_timeout"])

    def _finish(
        self, ticket: Ticket | None, target: Target | None, reason: str, wait: bool, timeout_s: float, resp: Any
    ) -> Any:
        """Fill ``resp`` (success, message, state) for a motion service."""
        deadline = time.monotonic() + self._timeout(timeout_s)
        resp.success, resp.message = self._await_ticket(ticket, reason, deadline)
        if resp.success and wait:
            resp.success, resp.message, sample = self._await_arrival(target, deadline)
        else:
            sample = self._poller.latest
        if hasattr(resp, "state"):
            if sample is not None:
                resp.state = self._state_msg(sample)
            if not wait and target is not None:
                for axis in ("pan", "tilt", "zoom"):
                    value = getattr(target, axis)
                    if value is not None:
                        setattr(resp.state, axis, float(value))
        return resp

    def _await_ticket(self, ticket: Ticket | None, reason: str, deadline: float) -> tuple[bool, str]:
        if ticket is None:
            return False, reason
        if not ticket.wait(max(0.0, deadline - time.monotonic())):
            return False, "timed out waiting for the camera to accept the command"
        if ticket.outcome is Outcome.SENT:
            return True, "sent"
        if ticket.outcome is Outcome.SUPERSEDED:
            return False, "superseded by a newer command before it was sent"
        return False, f"camera error: {ticket.error}" if ticket.error else str(ticket.outcome)

    def _await_arrival(self, target: Target | None, deadline: float) -> tuple[bool, str, StateSample | None]:
        """Until the head is still at ``target`` (or, without a target, still for a few polls)."""
        tol, ztol = float(self._p["arrival_tolerance"]), float(self._p["zoom_tolerance"])
        start = self._poller.latest
        seq = start.seq if start is not None else 0
        still = 0
        while True:
            left = deadline - time.monotonic()
            if left <= 0.0:
                return False, "timed out before arrival", self._poller.latest
            s = self._poller.wait_for(lambda _s: True, left, after_seq=seq)
            if s is None:
                return False, "timed out before arrival", self._poller.latest
            seq = s.seq
            still = 0 if s.head_moving else still + 1
            if target is not None:
                with self._lock:
                    if self._target is not target:
                        return False, "superseded by a newer command before arrival", s
                if not s.head_moving and target.reached(self._offsets.from_head(s.reading), tol, ztol):
                    return True, "arrived", s
            elif still >= 3:
                return True, "arrived (head still)", s

    def _srv_absolute(self, req: MovePtz.Request, resp: MovePtz.Response) -> MovePtz.Response:
        c = req.command
        t, tgt, reason = self._move(
            "absolute",
            finite_or_none(c.pan),
            finite_or_none(c.tilt),
            finite_or_none(c.zoom),
            speed=finite_or_none(c.speed),
        )
        return self._finish(t, tgt, reason, req.wait, req.timeout_s, resp)

    def _srv_relative(self, req: MovePtz.Request, resp: MovePtz.Response) -> MovePtz.Response:
        c = req.command
        t, tgt, reason = self._move(
            "relative",
            finite_or_none(c.pan),
            finite_or_none(c.tilt),
            finite_or_none(c.zoom),
            relative=True,
            speed=finite_or_none(c.speed),
        )
        return self._finish(t, tgt, reason, req.wait, req.timeout_s, resp)

    def _srv_center(self, req: CenterOnPixel.Request, resp: CenterOnPixel.Response) -> CenterOnPixel.Response:
        t, tgt, reason = self._center(req.target)
        return self._finish(t, tgt, reason, req.wait, req.timeout_s, resp)

    def _srv_area_zoom(self, req: AreaZoom.Request, resp: AreaZoom.Response) -> AreaZoom.Response:
        r = self._reading()
        w, h = self._image_size(req.image_width, req.image_height)
        box = (req.u_min, req.v_min, req.u_max, req.v_max)
        if r is None:
            t, tgt, reason = self._refuse("the current pose is not known yet")
        elif not all(math.isfinite(b) for b in box):
            t, tgt, reason = self._refuse("the box is not finite")
        else:
            try:
                pan, tilt, zoom = area_zoom_target(r, box, w, h, self._model.zoom)
            except ValueError as err:
                t, tgt, reason = self._refuse(str(err))
            else:
                zoom = min(max(zoom, self.limits.zoom_min), self.limits.zoom_max)
                t, tgt, reason = self._move("area_zoom", pan, tilt, zoom)
        return self._finish(t, tgt, reason, req.wait, req.timeout_s, resp)

    def _srv_set_zoom(self, req: SetZoom.Request, resp: SetZoom.Response) -> SetZoom.Response:
        try:
            zoom = zoom_target(
                self._model.zoom,
                finite_or_none(req.zoom),
                finite_or_none(req.magnification),
                finite_or_none(req.hfov),
            )
        except ValueError as err:
            t, tgt, reason = self._refuse(str(err))
        else:
            t, tgt, reason = self._move("set_zoom", None, None, zoom)
        return self._finish(t, tgt, reason, req.wait, req.timeout_s, resp)

    def _srv_look_at(self, req: LookAt.Request, resp: LookAt.Response) -> LookAt.Response:
        t, tgt, reason = self._look_at(req.target, finite_or_none(req.zoom))
        return self._finish(t, tgt, reason, req.wait, req.timeout_s, resp)

    def _srv_home(self, req: Trigger.Request, resp: Trigger.Response) -> Trigger.Response:
        ticket = self._untargeted("home", self._backend.home)
        deadline = time.monotonic() + float(self._p["wait_timeout"])
        resp.success, resp.message = self._await_ticket(ticket, "", deadline)
        return resp

    def _srv_preset(self, req: Preset.Request, resp: Preset.Response) -> Preset.Response:
        action, name, b = req.action.strip().lower(), req.name, self._backend
        if action == "goto":
            ticket = self._untargeted("goto_preset", lambda: b.goto_preset(name))
        elif action == "set":
            ticket = self._untargeted("set_preset", lambda: b.set_preset(name), supersedable=False)
        elif action == "remove":
            ticket = self._untargeted("remove_preset", lambda: b.remove_preset(name), supersedable=False)
        else:
            resp.success, resp.message = False, f"unknown action {req.action!r} (goto, set, remove)"
            return resp
        deadline = time.monotonic() + self._timeout(req.timeout_s)
        resp.success, resp.message = self._await_ticket(ticket, "", deadline)
        if resp.success and req.wait and action == "goto":
            resp.success, resp.message, _ = self._await_arrival(None, deadline)
        return resp

    def _srv_list_presets(self, req: ListPresets.Request, resp: ListPresets.Response) -> ListPresets.Response:
        out: list[Any] = []
        b = self._backend
        ticket = self._slot.submit("list_presets", lambda: out.extend(b.list_presets()), supersedable=False)
        resp.success, resp.message = self._await_ticket(ticket, "", time.monotonic() + float(self._p["timeout"]))
        resp.numbers = [int(pr.number) for pr in out]
        resp.names = [str(pr.name) for pr in out]
        return resp

    # ------------------------------------------------------------------------------------------------
    def destroy_node(self) -> None:
        """Stop a running velocity command (best effort), join the command worker, close the backend."""
        with self._lock:
            stop = self._velocity_active
            self._velocity_active = False
        if stop:
            t = self._slot.submit("stop", lambda: self._backend.velocity(0.0, 0.0, 0.0))
            t.wait(1.0)
        self._stop.set()
        self._poll_thread.join(timeout=float(self._p["state_timeout"]) + 1.0)
        self._slot.stop(timeout=float(self._p["timeout"]) + 1.0)
        self._backend.close()
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """``axis_ptz``: the PTZ node on its own."""
    return run_nodes([PtzNode], args)


if __name__ == "__main__":
    raise SystemExit(main())
