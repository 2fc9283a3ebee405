"""Commands that never fight (ROS-free): the commanded target, velocity mode, presets and arrival.

Every motion command goes through one :class:`Commander`, which owns the command bookkeeping the node used to
spread over its callbacks:

* **Target on acceptance.** An order carries a *spec* (how the new target follows from the previous one). The
  spec is evaluated by the command worker when the order is actually sent, against the target the camera last
  *accepted*; a command that fails or is refused leaves that target unchanged, so later relative moves never
  add up onto a pose the head was never sent to. Specs of orders that a newer one superseded before they were
  sent are composed into the newer one (a burst of relative steps still adds up exactly).
* **Velocity mode.** A velocity command arms the watchdog; any other motion command disarms it when it is
  submitted, so the watchdog can never stop a home/preset/absolute move part-way. If that command then fails,
  the worker stops the continuous motion it was meant to replace (the head is never left turning).
* **Presets and home.** ``home`` is an absolute move to the home pose (pan 0, tilt 0, widest zoom of the head).
  A preset's pose is known when this node stored it or has seen the head settle there; a goto to a known pose
  is tracked to that pose like any move; for an unknown one, arrival means the head settled (and its pose is
  learned).
* **Arrival.** :meth:`Commander.track` follows an order: accepted or not, then the state samples until the head
  is at the target, settled elsewhere (with where and how far), superseded, or out of time.

Units: REP-103 radians in joint coordinates (the calibrated encoder offsets applied), VAPIX zoom units.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Iterator

from axis_ptz_ros2.ptz.arrival import track
from axis_ptz_ros2.ptz.backend import OutOfLimits, PtzBackend, PtzBackendError, PtzLimitsRos, PtzReading
from axis_ptz_ros2.ptz.command_slot import CommandSlot, Ticket
from axis_ptz_ros2.ptz.control import JointOffsets, Target, merge_target, normalize_target
from axis_ptz_ros2.ptz.orders import CommanderStats, Order, Progress, Spec, Tolerances, const, rate_value, then
from axis_ptz_ros2.ptz.state import StatePoller, StateSample


class Commander:
    """The one path of every PTZ command (see the module docstring). Thread-safe."""

    def __init__(
        self,
        backend: PtzBackend,
        slot: CommandSlot,
        poller: StatePoller,
        limits: Callable[[], PtzLimitsRos],
        tolerances: Tolerances,
        offsets: JointOffsets | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        """``limits`` returns the limits in joint coordinates; ``offsets`` map head readings to joints;
        ``tolerances`` may be replaced later by assigning :attr:`tol`."""
        self._backend = backend
        self._slot = slot
        self._poller = poller
        self._limits = limits
        self._offsets = offsets or JointOffsets()
        self.tol = tolerances
        self._clock = clock
        self._lock = threading.RLock()
        self._gen = 0
        self._chain: Spec | None = None  # specs of submitted, not yet started orders (composed)
        self._accepted: Target | None = None  # the target the camera last accepted
        self._inflight: Target | None = None  # the target of the order being sent
        self._inflight_busy = False
        self._velocity_active = False  # watchdog armed
        self._continuous = False  # the camera may be in a continuous motion we started
        self._last_velocity = -math.inf
        self._last_cmd = -math.inf
        self._still_polls = 0
        self._presets: dict[str, Target] = {}
        self._cap: float | None = None  # drive-safe zoom cap in force
        self._requested_zoom: float | None = None  # the operator's zoom (restored when the cap lifts)
        self._last_enforce = -math.inf
        self._slow = False  # the camera's move speed was last set below full speed
        self.stats = CommanderStats()

    # -- state ----------------------------------------------------------------------------------------
    def reading(self) -> PtzReading | None:
        """The newest measured pose in joint coordinates."""
        s = self._poller.latest
        return None if s is None else self._offsets.from_head(s.reading)

    @property
    def target(self) -> Target | None:
        """The target the camera last accepted (None: unknown, e.g. after a velocity command)."""
        with self._lock:
            return self._accepted

    @property
    def velocity_active(self) -> bool:
        """A velocity command is running (its watchdog is armed)."""
        with self._lock:
            return self._velocity_active

    @property
    def generation(self) -> int:
        """Increases with every motion command submitted."""
        with self._lock:
            return self._gen

    def preset_pose(self, name: str) -> Target | None:
        """The pose of a preset as far as this node knows it."""
        with self._lock:
            return self._presets.get(name)

    def home_target(self) -> Target:
        """Pan 0, tilt 0 of the head (encoder offsets applied) at its widest zoom."""
        lim = self._limits()
        return Target(self._offsets.pan, self._offsets.tilt, float(lim.zoom_min))

    def moving_expected(self, r: PtzReading) -> bool:
        """A velocity command runs, or the accepted target is not reached yet."""
        with self._lock:
            if self._velocity_active:
                return True
            t = self._capped(self._accepted)
        return t is not None and not t.reached(r, self.tol.pan_tilt_rad, self.tol.zoom_units)

    # -- drive-safe zoom ---------------------------------------------------------------------------------
    @property
    def zoom_cap(self) -> float | None:
        """The zoom cap in force (None: not capped)."""
        with self._lock:
            return self._cap

    @property
    def requested_zoom(self) -> float | None:
        """The zoom the operator last commanded (None: unknown, e.g. after a continuous zoom)."""
        with self._lock:
            return self._requested_zoom

    def _capped(self, t: Target | None) -> Target | None:
        if t is None or self._cap is None or t.zoom is None or t.zoom <= self._cap:
            return t
        return Target(t.pan, t.tilt, self._cap)

    def set_zoom_cap(self, cap: float | None) -> Order | None:
        """Put a zoom cap in force (zooming out to it if needed) or lift it (None: restoring the operator's
        zoom). Returns the order sent, if any. Never ends velocity mode, never supersedes a tracked order."""
        with self._lock:
            if cap == self._cap:
                return None
            self._cap = cap
            r = self.reading()
            if cap is not None:
                if self._requested_zoom is None and r is not None:
                    self._requested_zoom = r.zoom  # what to restore when the cap lifts
                want = self._requested_zoom
                if want is None or (want <= cap and (r is None or r.zoom <= cap + self.tol.zoom_units)):
                    return None
                return self._zoom_order("zoom_cap", want)
            if self._requested_zoom is None or r is None or abs(r.zoom - self._requested_zoom) <= self.tol.zoom_units:
                return None
            return self._zoom_order("zoom_restore", self._requested_zoom)

    def _zoom_order(self, label: str, zoom: float) -> Order:
        """Set the zoom (capped by :meth:`_run`), keeping pan/tilt targets and the operator's order alive."""

        def spec(base: Target | None, r: PtzReading | None) -> Target | None:
            return merge_target(base, r, None, None, zoom, False)

        def action(t: Target | None) -> None:
            assert t is not None
            assert t.zoom is not None
            self._backend.move_to(None, None, t.zoom)

        self._last_enforce = self._clock()
        return self._submit(label, spec, action, internal=True)

    # -- submission -----------------------------------------------------------------------------------
    def _refuse(self, label: str, reason: str) -> Order:
        with self._lock:
            self.stats.refused += 1
            self.stats.last_refusal = reason
        return Order(label, reason=reason)

    def _check(self, target: Target | None) -> tuple[Target | None, str]:
        if target is None:
            return None, ""
        lim = self._limits()
        t = normalize_target(target, lim)
        if t.zoom is not None and math.isfinite(t.zoom):
            t = Target(t.pan, t.tilt, float(round(t.zoom)))
        if t.empty:
            return None, "nothing to move: every axis is NaN"
        reason = lim.violation(t.pan, t.tilt, t.zoom)
        return (None, f"refused, not sent: {reason}") if reason is not None else (t, "")

    def _submit(
        self,
        label: str,
        spec: Spec,
        action: Callable[[Target | None], None],
        *,
        velocity: bool = False,
        internal: bool = False,
    ) -> Order:
        """Check the provisional target, then queue the order (latest motion wins). ``internal`` orders (the
        drive-safe cap) keep the operator's order generation and velocity mode."""
        with self._lock:
            base = self._inflight if self._inflight_busy else self._accepted
            chain = spec if self._chain is None else then(self._chain, spec)
            r = self.reading()
            try:
                provisional = chain(base, r)
            except ValueError as err:
                return self._refuse(label, str(err))
            target, reason = self._check(provisional)
            if reason:
                return self._refuse(label, reason)
            if not internal:
                self._gen += 1
            order = Order(label, gen=self._gen, target=target)
            self._chain = chain
            self._last_cmd = self._clock()
            if not velocity and not internal:
                self._velocity_active = False  # any other motion command ends velocity mode
            order.ticket = self._slot.submit(label, lambda: self._run(order, action, velocity, internal))
            return order

    def _run(
        self, order: Order, action: Callable[[Target | None], None], velocity: bool, internal: bool = False
    ) -> None:
        """In the command worker: evaluate the composed spec against the accepted target, send, record."""
        with self._lock:
            chain, self._chain = self._chain, None
            try:
                target, reason = self._check(chain(self._accepted, self.reading()) if chain else self._accepted)
            except ValueError as err:
                target, reason = None, str(err)
            if reason:
                self.stats.refused_at_send += 1
                self.stats.last_refusal = reason
            else:
                self._inflight, self._inflight_busy = target, True
            sent = self._capped(target)
        try:
            if reason:
                raise OutOfLimits(reason)
            action(sent)
        except PtzBackendError:
            with self._lock:
                self._inflight, self._inflight_busy = None, False
                halt = self._continuous and not velocity and self._gen == order.gen
            if halt:  # this command was to replace a continuous motion: do not leave the head turning
                try:
                    self._backend.velocity(0.0, 0.0, 0.0)
                except PtzBackendError:
                    pass
                else:
                    with self._lock:
                        self._continuous = False
                        self.stats.halted_after_failure += 1
            raise
        with self._lock:
            self._inflight, self._inflight_busy = None, False
            self._accepted = target
            order.target = target
            order.accepted_mono = self._clock()
            if not internal:
                if target is not None and target.zoom is not None:
                    self._requested_zoom = target.zoom
                elif order.zooming or (target is None and order.label not in ("velocity", "stop")):
                    self._requested_zoom = None  # a continuous zoom or a preset of unknown pose
            if not velocity:
                self._continuous = False

    def move(
        self,
        label: str,
        pan: float | None,
        tilt: float | None,
        zoom: float | None,
        *,
        relative: bool = False,
        speed: float | None = None,
    ) -> Order:
        """Absolute (None keeps an axis) or relative (offsets added to the target) move."""
        if pan is None and tilt is None and zoom is None:
            return self._refuse(label, "nothing to move: every axis is NaN")

        def spec(base: Target | None, r: PtzReading | None) -> Target | None:
            return merge_target(base, r, pan, tilt, zoom, relative)

        return self._submit(label, spec, self._move_action(speed))

    def move_to(self, label: str, target: Target, speed: float | None = None) -> Order:
        """Absolute move to a full or partial target (None axes keep their previous target)."""
        return self.move(label, target.pan, target.tilt, target.zoom, speed=speed)

    def _move_action(self, speed: float | None) -> Callable[[Target | None], None]:
        """The camera keeps a move speed once set (VAPIX ``speed`` is a setting, not a per-move argument): a move
        without a speed after one with a speed sends full speed again, so a slow move never leaves the head slow."""

        def action(t: Target | None) -> None:
            assert t is not None
            hp, ht = self._offsets.to_head(t.pan, t.tilt)
            sent = speed if speed is not None else (1.0 if self._slow else None)
            self._backend.move_to(hp, ht, t.zoom, sent)
            self._slow = sent is not None and sent < 1.0  # only the command worker runs this

        return action

    def home(self) -> Order:
        """An absolute move to :meth:`home_target`."""
        return self.move_to("home", self.home_target())

    def goto_preset(self, name: str) -> Order:
        """Go to a preset stored in the camera; tracked to its pose when this node knows it."""
        with self._lock:
            pose = self._presets.get(name)
        order = self._submit("goto_preset", const(pose), lambda _t: self._backend.goto_preset(name))
        order.preset = name
        return order

    def set_preset(self, name: str) -> Ticket:
        """Store the current pose under ``name`` (never superseded; velocity mode untouched). The pose is
        remembered when the head was still."""

        def run() -> None:
            self._backend.set_preset(name)
            s = self._poller.latest
            with self._lock:
                if s is not None and not s.head_moving and not self._continuous:
                    r = self._offsets.from_head(s.reading)
                    self._presets[name] = Target(r.pan, r.tilt, r.zoom)
                else:
                    self._presets.pop(name, None)

        return self._slot.submit("set_preset", run, supersedable=False)

    def remove_preset(self, name: str) -> Ticket:
        """Delete a preset (never superseded)."""

        def run() -> None:
            self._backend.remove_preset(name)
            with self._lock:
                self._presets.pop(name, None)

        return self._slot.submit("remove_preset", run, supersedable=False)

    def velocity(self, pan_rate: float, tilt_rate: float, zoom_rate: float) -> Order:
        """Continuous motion (rad/s, zoom −1..1); every field must be finite; all zero stops."""
        try:
            vals = (rate_value(pan_rate, "pan_rate"), rate_value(tilt_rate, "tilt_rate"))
            z = max(-1.0, min(1.0, rate_value(zoom_rate, "zoom_rate")))
        except ValueError as err:
            return self._refuse("velocity", str(err))
        moving = vals[0] != 0.0 or vals[1] != 0.0 or z != 0.0

        def action(_t: Target | None) -> None:
            zr = z
            if zr > 0.0 and self._cap is not None:  # drive-safe: no zooming in past the cap
                r = self.reading()
                if r is None or r.zoom >= self._cap - self.tol.zoom_units:
                    zr = 0.0
            self._backend.velocity(vals[0], vals[1], zr)

        with self._lock:
            order = self._submit("velocity" if moving else "stop", const(None), action, velocity=moving)
            order.zooming = z != 0.0
            if not order.refused:
                self._velocity_active = moving
                self._last_velocity = self._clock()
                self._continuous = self._continuous or moving
            return order

    def stop(self) -> Order:
        """Stop pan, tilt and zoom now (also ends velocity mode)."""
        return self.velocity(0.0, 0.0, 0.0)

    def check_velocity_timeout(self) -> bool:
        """Watchdog tick: stop a velocity command older than the timeout. Returns whether it stopped one.
        Checked and submitted under one lock, so no other command can slip in between and be stopped."""
        with self._lock:
            if not self._velocity_active or self._clock() - self._last_velocity < self.tol.velocity_timeout_s:
                return False
            self.stop()
            return True

    # -- state samples ----------------------------------------------------------------------------------
    def on_sample(self, sample: StateSample) -> bool:
        """Drop a target the head has evidently settled away from (reboot, another client moved it) and hold
        a zoom cap in force (a preset or another client may zoom past it). Returns True when it dropped the
        target."""
        with self._lock:
            r = self._offsets.from_head(sample.reading)
            if (
                self._cap is not None
                and r.zoom > self._cap + self.tol.zoom_units
                and self._slot.idle
                and self._chain is None
                and self._clock() - self._last_enforce > 0.5
            ):
                self._zoom_order("zoom_cap", r.zoom if self._requested_zoom is None else self._requested_zoom)
            target = self._capped(self._accepted)
            if target is None:
                self._still_polls = 0
                return False
            self._still_polls = 0 if sample.head_moving else self._still_polls + 1
            if (
                self._still_polls >= 5
                and self._slot.idle
                and self._chain is None
                and self._clock() - self._last_cmd > 2.0
                and not target.reached(r, self.tol.pan_tilt_rad, self.tol.zoom_units)
            ):
                self._accepted = None
                return True
            return False

    # -- following an order -----------------------------------------------------------------------------
    def track(
        self, order: Order, timeout_s: float, cancelled: Callable[[], bool] = lambda: False
    ) -> Iterator[Progress]:
        """Follow ``order`` until it ends; the last item has ``done`` set. Stops yielding (without a final
        item) as soon as ``cancelled()`` is true; the caller then decides what to do with the head
        (:func:`axis_ptz_ros2.ptz.arrival.track`)."""
        return track(self, self._poller, self._clock, order, timeout_s, cancelled)

    def to_joints(self, head: PtzReading) -> PtzReading:
        """A head reading in joint coordinates (the calibrated encoder offsets applied)."""
        return self._offsets.from_head(head)

    def capped_target(self, order: Order) -> Target | None:
        """The target of ``order`` as sent (the drive-safe zoom cap in force applied)."""
        with self._lock:
            return self._capped(order.target)

    def learn(self, order: Order, r: PtzReading) -> None:
        """A goto of ``order`` ended at ``r``: that is its preset's pose and the accepted target (unless a newer
        order came)."""
        with self._lock:
            if self._gen == order.gen:
                pose = Target(r.pan, r.tilt, r.zoom)
                self._presets[order.preset] = pose
                self._accepted = pose

    def refuse(self, label: str, reason: str) -> Order:
        """Count and return a refusal decided outside the commander (e.g. a field that is ±inf)."""
        return self._refuse(label, reason)
