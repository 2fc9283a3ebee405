"""Health of a PTZ head (ROS-free): how old the state is, when it counts as stale, the diagnostic level and
the values the node publishes on ``/diagnostics``.

Levels (DiagnosticStatus's, as ints): STALE before the first poll; ERROR when the newest state is older than
:func:`stale_after` (a hung poll) or five polls in a row failed; WARN while polls fail; OK otherwise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from axis_ptz_ros2.ptz.command_slot import SlotStats
from axis_ptz_ros2.ptz.orders import CommanderStats
from axis_ptz_ros2.ptz.state import PollStats, StateSample

DIAG_OK, DIAG_WARN, DIAG_ERROR, DIAG_STALE = 0, 1, 2, 3
FAILURES_FOR_ERROR = 5  #: consecutive failed polls after which the camera counts as not answering

DiagValue = float | int | str | bool


@dataclass(frozen=True, slots=True)
class Health:
    """A verdict with the figures it was made from."""

    level: int
    message: str
    age_s: float  # inf before the first sample
    stale_after_s: float


def stale_after(period_s: float, state_timeout_s: float) -> float:
    """State older than this is stale: five periods, two poll timeouts, at least one second."""
    return max(1.0, 5.0 * period_s, state_timeout_s * 2.0)


def state_age(sample: StateSample | None, now_ns: int) -> float:
    """Seconds since ``sample`` was measured (inf without one)."""
    return math.inf if sample is None else max(0.0, (now_ns - sample.reading.stamp_ns) / 1e9)


def judge(stats: PollStats, age_s: float, stale_s: float) -> Health:
    """The diagnostic level and message of the state polling."""
    if stats.ok == 0 and stats.failed == 0:
        level, msg = DIAG_STALE, "no state poll yet"
    elif math.isfinite(age_s) and age_s > stale_s:
        level, msg = DIAG_ERROR, f"state is stale: the newest is {age_s:.1f} s old (> {stale_s:.1f} s)"
        if stats.last_error:
            msg += f"; last poll error: {stats.last_error}"
    elif stats.consecutive_failures >= FAILURES_FOR_ERROR:
        level, msg = DIAG_ERROR, f"camera not answering: {stats.last_error}"
    elif stats.consecutive_failures > 0:
        level, msg = DIAG_WARN, f"state poll failing: {stats.last_error}"
    else:
        level, msg = DIAG_OK, "ok"
    return Health(level, msg, age_s, stale_s)


def diagnostic_values(
    health: Health,
    poll: PollStats,
    restarts: int,
    last_crash: str,
    slot: SlotStats,
    cmd: CommanderStats,
) -> dict[str, DiagValue]:
    """The key/values of the node's PTZ diagnostic status (poller, command worker, commander)."""
    age = health.age_s
    return {
        "state_rate_hz": poll.rate_hz,
        "state_age_s": age if math.isfinite(age) else -1.0,
        "state_stale_after_s": health.stale_after_s,
        "poller_restarts": restarts,
        "poller_last_crash": last_crash,
        "polls_ok": poll.ok,
        "polls_failed": poll.failed,
        "consecutive_failures": poll.consecutive_failures,
        "last_poll_error": poll.last_error,
        "last_poll_s": poll.last_poll_s,
        "commands_submitted": slot.submitted,
        "commands_sent": slot.sent,
        "commands_failed": slot.failed,
        "commands_superseded": slot.superseded,
        "commands_refused": cmd.refused + cmd.refused_at_send,
        "last_refusal": cmd.last_refusal,
        "halted_after_failed_command": cmd.halted_after_failure,
        "last_command_error": slot.last_error,
        "last_command_latency_s": slot.last_latency_s,
    }
