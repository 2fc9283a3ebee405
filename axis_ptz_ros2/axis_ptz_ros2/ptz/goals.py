"""Following an order to its end (ROS-free): services that wait, the ``ptz/move`` goal and its cancel policy.

* :meth:`Follower.follow`: a service's answer: accepted by the camera (``wait`` false) or arrived (``wait``
  true), with the newest sample.
* :meth:`Follower.run_goal`: a long-running goal with feedback; it ends succeeded (arrived), cancelled (the
  head is stopped, unless a newer command already drives it, and the answer says where it stopped), or aborted
  (refused, failed, timed out, or pre-empted by a newer goal, which then owns the head: nothing is stopped).
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from dataclasses import dataclass
from enum import StrEnum

from axis_ptz_ros2.ptz.commander import Commander
from axis_ptz_ros2.ptz.control import JointOffsets
from axis_ptz_ros2.ptz.orders import Order, Progress, describe, wait_accepted
from axis_ptz_ros2.ptz.preemption import Preemption
from axis_ptz_ros2.ptz.state import StatePoller, StateSample

CANCEL_SETTLE_S = 2.0  #: how long a cancelled goal waits for the head to report standing still


def wait_timeout(timeout_s: float, default_s: float) -> float:
    """A request's ``timeout_s`` when it is a positive finite number, else the default (``wait_timeout``)."""
    return float(timeout_s) if math.isfinite(timeout_s) and timeout_s > 0.0 else float(default_s)


class GoalStatus(StrEnum):
    """How a goal ended."""

    SUCCEEDED = "succeeded"
    CANCELED = "canceled"
    ABORTED = "aborted"


@dataclass(frozen=True, slots=True)
class GoalEnd:
    """The end of a goal: status, message for people, the newest sample (None before the first)."""

    status: GoalStatus
    message: str
    sample: StateSample | None


class GoalBook:
    """The orders of accepted goals until they run, and which goal pre-empted which (latest wins)."""

    def __init__(self) -> None:
        """No goal."""
        self._lock = threading.Lock()
        self._orders: dict[bytes, Order] = {}
        self._preemption = Preemption()

    def accept(self, key: bytes, order: Order) -> None:
        """Goal ``key`` was accepted with ``order``; a valid order pre-empts the running goal (a refused one
        does not: it ends aborted with the reason and the running goal keeps the head)."""
        with self._lock:
            self._orders[key] = order
        if not order.refused:
            self._preemption.start(key)

    def take(self, key: bytes) -> Order | None:
        """The order of goal ``key`` (once)."""
        with self._lock:
            return self._orders.pop(key, None)

    def preempted(self, key: bytes) -> bool:
        """Whether a newer goal pre-empted ``key``."""
        return self._preemption.preempted(key)

    def finish(self, key: bytes) -> None:
        """Goal ``key`` ended."""
        self._preemption.finish(key)


class Follower:
    """Follows orders of one :class:`Commander` (see the module docstring)."""

    def __init__(self, cmd: Commander, poller: StatePoller, offsets: JointOffsets, command_timeout_s: float) -> None:
        """``command_timeout_s``: how long a stop for a cancel may take to be accepted."""
        self._cmd = cmd
        self._poller = poller
        self._offsets = offsets
        self._command_timeout_s = command_timeout_s

    def follow(self, order: Order, wait: bool, timeout_s: float) -> tuple[bool, str, StateSample | None]:
        """Accepted (``wait`` false) or arrived (``wait`` true): success, message, the last sample."""
        if not wait:
            ok, msg = wait_accepted(order.ticket, order.reason, timeout_s)
            return ok, msg, self._poller.latest
        last = Progress(self._poller.latest, order.target, True, False, "no progress")
        for step in self._cmd.track(order, timeout_s):
            last = step
        return last.success, last.message, last.sample

    def run_goal(
        self,
        order: Order,
        timeout_s: float,
        cancel_requested: Callable[[], bool],
        preempted: Callable[[], bool],
        feedback: Callable[[Progress], None],
    ) -> GoalEnd:
        """Follow ``order`` with ``feedback`` (every progress step with a sample) until it ends, is cancelled
        or is pre-empted."""
        last: Progress | None = None
        for last in self._cmd.track(order, timeout_s, lambda: cancel_requested() or preempted()):
            if last.done:
                break
            if last.sample is not None:
                feedback(last)
        was_preempted = preempted()
        if last is not None and last.done and not was_preempted:
            success, message, sample = last.success, last.message, last.sample
        elif cancel_requested() and not was_preempted:
            success, (message, sample) = False, self.stop_for_cancel(order)
        else:
            success, message, sample = False, "pre-empted by a newer ptz/move goal", self._poller.latest
        if success:
            status = GoalStatus.SUCCEEDED
        elif cancel_requested() and not was_preempted:
            status = GoalStatus.CANCELED
        else:
            status = GoalStatus.ABORTED
        return GoalEnd(status, message, sample)

    def preset(self, action: str, name: str, wait: bool, timeout_s: float) -> tuple[bool, str]:
        """``goto`` (followed like a move), ``set`` or ``remove`` a preset (case and blanks of ``action``
        ignored); an unknown action is refused."""
        verb = action.strip().lower()
        if verb == "goto":
            ok, msg, _ = self.follow(self._cmd.goto_preset(name), wait, timeout_s)
            return ok, msg
        if verb in ("set", "remove"):
            ticket = self._cmd.set_preset(name) if verb == "set" else self._cmd.remove_preset(name)
            return wait_accepted(ticket, "", timeout_s)
        return False, f"unknown action {action!r} (goto, set, remove)"

    def stop_for_cancel(self, order: Order) -> tuple[str, StateSample | None]:
        """Stop the head (only if nothing newer was commanded since) and report where it stopped."""
        poller = self._poller
        if self._cmd.generation != order.gen:
            return "cancelled (a newer command is already in charge of the head)", poller.latest
        stop = self._cmd.stop()
        ok, why = wait_accepted(stop.ticket, stop.reason, self._command_timeout_s)
        if not ok:
            return f"cancelled, but stopping the head failed: {why}", poller.latest
        s = poller.latest
        s = poller.wait_for(lambda x: not x.head_moving, CANCEL_SETTLE_S, after_seq=s.seq if s else 0) or poller.latest
        where = describe(self._offsets.from_head(s.reading)) if s is not None else "an unknown pose"
        return f"cancelled: the head stopped at {where}", s
