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
from dataclasses import dataclass, field

from axis_ptz_ros2.geometry import wrap_angle
from axis_ptz_ros2.ptz.backend import OutOfLimits, PtzBackend, PtzBackendError, PtzLimitsRos, PtzReading
from axis_ptz_ros2.ptz.command_slot import CommandSlot, Outcome, Ticket
from axis_ptz_ros2.ptz.control import JointOffsets, Target, merge_target, normalize_target
from axis_ptz_ros2.ptz.state import StatePoller, StateSample

SETTLE_POLLS = 5  #: consecutive still polls after which a head that is not at its target has stopped short
SETTLE_S = 1.0  #: and at least this long after the camera accepted the command (a real head starts late)
UNTRACKED_STILL_POLLS = 3  #: still polls that count as "arrived" for a move to an unknown pose

#: How a new target follows from the accepted one and the measured pose (raises ValueError if it cannot).
Spec = Callable[[Target | None, PtzReading | None], Target | None]


def _then(first: Spec, second: Spec) -> Spec:
    return lambda base, r: second(first(base, r), r)


def _const(target: Target | None) -> Spec:
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
    """One step of :meth:`Commander.track`: the newest sample, the remaining error and, once ``done``, the
    outcome."""

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
            chain = spec if self._chain is None else _then(self._chain, spec)
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
        order = self._submit("goto_preset", _const(pose), lambda _t: self._backend.goto_preset(name))
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
            order = self._submit("velocity" if moving else "stop", _const(None), action, velocity=moving)
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
        item) as soon as ``cancelled()`` is true; the caller then decides what to do with the head."""
        deadline = self._clock() + timeout_s
        if order.ticket is None:
            yield Progress(self._poller.latest, None, True, False, order.reason)
            return
        ticket = order.ticket
        while not ticket.wait(0.05):
            if cancelled():
                return
            if self._clock() >= deadline:
                yield Progress(self._poller.latest, order.target, True, False, "timed out waiting for the camera")
                return
        ok, msg = wait_accepted(ticket, "", 0.0)
        if not ok:
            yield Progress(self._poller.latest, order.target, True, False, msg)
            return
        yield from self._arrival(order, deadline, cancelled)

    def _arrival(self, order: Order, deadline: float, cancelled: Callable[[], bool]) -> Iterator[Progress]:
        target = order.target
        start = self._poller.latest
        seq = start.seq if start is not None else 0
        still, moved = 0, False
        while True:
            if cancelled():
                return
            left = deadline - self._clock()
            s = self._poller.wait_for(lambda _s: True, min(max(left, 0.0), 0.1), after_seq=seq) if left > 0 else None
            if s is None:
                if self._clock() >= deadline:
                    r = self.reading()
                    where = f"; the head is at {describe(r)}" if r is not None else ""
                    yield Progress(self._poller.latest, target, True, False, "timed out before arrival" + where)
                    return
                continue
            seq = s.seq
            r = self._offsets.from_head(s.reading)
            with self._lock:
                target = self._capped(order.target)
            err = remaining_error(target, r)
            with self._lock:
                newer = self._gen != order.gen
            if newer:
                yield Progress(s, target, True, False, "superseded by a newer command before arrival", err)
                return
            still = 0 if s.head_moving else still + 1
            moved = moved or s.head_moving
            if target is not None:
                if not s.head_moving and target.reached(r, self.tol.pan_tilt_rad, self.tol.zoom_units):
                    yield Progress(s, target, True, True, f"arrived at {describe(r)}", err)
                    return
                if still >= SETTLE_POLLS and self._clock() - order.accepted_mono >= SETTLE_S:
                    msg = (
                        f"the head stopped at {describe(r)}, short of the target (remaining: pan "
                        f"{math.degrees(err[0]) if math.isfinite(err[0]) else 0.0:.3f} deg, tilt "
                        f"{math.degrees(err[1]) if math.isfinite(err[1]) else 0.0:.3f} deg, zoom "
                        f"{err[2] if math.isfinite(err[2]) else 0.0:g})"
                    )
                    if order.preset:
                        msg += "; the preset may have been changed by another client (its pose is re-learned)"
                        self._learn(order, r)
                    yield Progress(s, target, True, False, msg, err)
                    return
            elif still >= UNTRACKED_STILL_POLLS and (moved or self._clock() - order.accepted_mono >= SETTLE_S):
                note = ""
                if order.preset:
                    note = f" (the pose of preset {order.preset!r} was not known; now learned)"
                    self._learn(order, r)
                yield Progress(s, None, True, True, f"settled at {describe(r)}{note}", err)
                return
            yield Progress(s, target, False, False, "moving", err)

    def _learn(self, order: Order, r: PtzReading) -> None:
        with self._lock:
            if self._gen == order.gen:
                pose = Target(r.pan, r.tilt, r.zoom)
                self._presets[order.preset] = pose
                self._accepted = pose

    def refuse(self, label: str, reason: str) -> Order:
        """Count and return a refusal decided outside the commander (e.g. a field that is ±inf)."""
        return self._refuse(label, reason)


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


class Preemption:
    """Latest-wins bookkeeping of long-running goals: starting a goal pre-empts the one running (ROS-free)."""

    def __init__(self) -> None:
        """No goal running."""
        self._lock = threading.Lock()
        self._current: bytes | None = None
        self._preempted: set[bytes] = set()

    def start(self, key: bytes) -> None:
        """``key`` becomes the running goal; the previous one (if any) is pre-empted."""
        with self._lock:
            if self._current is not None and self._current != key:
                self._preempted.add(self._current)
            self._current = key

    def preempted(self, key: bytes) -> bool:
        """Whether a newer goal pre-empted ``key``."""
        with self._lock:
            return key in self._preempted

    def finish(self, key: bytes) -> None:
        """``key`` ended."""
        with self._lock:
            self._preempted.discard(key)
            if self._current == key:
                self._current = None
