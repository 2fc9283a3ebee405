"""Following one PTZ order until it ends (ROS-free): accepted or not, then the state samples until the head is at
the target, settled elsewhere (with where and how far), superseded, or out of time.

:func:`track` reads the :class:`~axis_ptz_ros2.ptz.commander.Commander` through :class:`Followed` (what it needs
of it, nothing more); ``Commander.track`` calls it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from typing import Protocol

from axis_ptz_ros2.ptz.backend import PtzReading
from axis_ptz_ros2.ptz.control import Target
from axis_ptz_ros2.ptz.orders import Order, Progress, Tolerances, describe, remaining_error, wait_accepted
from axis_ptz_ros2.ptz.state import StatePoller

SETTLE_POLLS = 5  #: consecutive still polls after which a head that is not at its target has stopped short
SETTLE_S = 1.0  #: and at least this long after the camera accepted the command (a real head starts late)
UNTRACKED_STILL_POLLS = 3  #: still polls that count as "arrived" for a move to an unknown pose


class Followed(Protocol):
    """What following an order needs of the commander."""

    tol: Tolerances

    @property
    def generation(self) -> int:
        """Increases with every motion command submitted."""
        ...

    def reading(self) -> PtzReading | None:
        """The newest measured pose in joint coordinates."""
        ...

    def to_joints(self, head: PtzReading) -> PtzReading:
        """A head reading in joint coordinates."""
        ...

    def capped_target(self, order: Order) -> Target | None:
        """The target of ``order`` as sent (the drive-safe zoom cap in force applied)."""
        ...

    def learn(self, order: Order, r: PtzReading) -> None:
        """A goto ended at ``r``: that is its preset's pose (unless a newer order came)."""
        ...


def track(
    commander: Followed,
    poller: StatePoller,
    clock: Callable[[], float],
    order: Order,
    timeout_s: float,
    cancelled: Callable[[], bool] = lambda: False,
) -> Iterator[Progress]:
    """Follow ``order`` until it ends; the last item has ``done`` set. Stops yielding (without a final item) as
    soon as ``cancelled()`` is true; the caller then decides what to do with the head."""
    deadline = clock() + timeout_s
    if order.ticket is None:
        yield Progress(poller.latest, None, True, False, order.reason)
        return
    ticket = order.ticket
    while not ticket.wait(0.05):
        if cancelled():
            return
        if clock() >= deadline:
            yield Progress(poller.latest, order.target, True, False, "timed out waiting for the camera")
            return
    ok, msg = wait_accepted(ticket, "", 0.0)
    if not ok:
        yield Progress(poller.latest, order.target, True, False, msg)
        return
    yield from _arrival(commander, poller, clock, order, deadline, cancelled)


def _arrival(
    commander: Followed,
    poller: StatePoller,
    clock: Callable[[], float],
    order: Order,
    deadline: float,
    cancelled: Callable[[], bool],
) -> Iterator[Progress]:
    target = order.target
    start = poller.latest
    seq = start.seq if start is not None else 0
    still, moved = 0, False
    while True:
        if cancelled():
            return
        left = deadline - clock()
        s = poller.wait_for(lambda _s: True, min(max(left, 0.0), 0.1), after_seq=seq) if left > 0 else None
        if s is None:
            if clock() >= deadline:
                r = commander.reading()
                where = f"; the head is at {describe(r)}" if r is not None else ""
                yield Progress(poller.latest, target, True, False, "timed out before arrival" + where)
                return
            continue
        seq = s.seq
        r = commander.to_joints(s.reading)
        target = commander.capped_target(order)
        err = remaining_error(target, r)
        newer = commander.generation != order.gen
        if newer:
            yield Progress(s, target, True, False, "superseded by a newer command before arrival", err)
            return
        still = 0 if s.head_moving else still + 1
        moved = moved or s.head_moving
        if target is not None:
            if not s.head_moving and target.reached(r, commander.tol.pan_tilt_rad, commander.tol.zoom_units):
                yield Progress(s, target, True, True, f"arrived at {describe(r)}", err)
                return
            if still >= SETTLE_POLLS and clock() - order.accepted_mono >= SETTLE_S:
                msg = (
                    f"the head stopped at {describe(r)}, short of the target (remaining: pan "
                    f"{math.degrees(err[0]) if math.isfinite(err[0]) else 0.0:.3f} deg, tilt "
                    f"{math.degrees(err[1]) if math.isfinite(err[1]) else 0.0:.3f} deg, zoom "
                    f"{err[2] if math.isfinite(err[2]) else 0.0:g})"
                )
                if order.preset:
                    msg += "; the preset may have been changed by another client (its pose is re-learned)"
                    commander.learn(order, r)
                yield Progress(s, target, True, False, msg, err)
                return
        elif still >= UNTRACKED_STILL_POLLS and (moved or clock() - order.accepted_mono >= SETTLE_S):
            note = ""
            if order.preset:
                note = f" (the pose of preset {order.preset!r} was not known; now learned)"
                commander.learn(order, r)
            yield Progress(s, None, True, True, f"settled at {describe(r)}{note}", err)
            return
        yield Progress(s, target, False, False, "moving", err)
