"""When an H.264 stage grants an on-demand IDR at once: tests that ask for one wait for this instead of sleeping
past the stage's rate limit (test tooling)."""

from __future__ import annotations

from axis_ptz_ros2.streaming.h264 import IDR_MIN_INTERVAL_S, H264Stage
from axis_ptz_ros2.streaming.start_points import StartPoints


def idr_granted_at_once(stage: H264Stage, starts: StartPoints) -> bool:
    """True when ``stage`` has no IDR pending or still due (a new subscriber's second one included), ``starts``
    has no start-point repeat still due (a new viewer's IDRs 1.2, 2.4 and 4.8 s after it appears) and the stage
    granted its last IDR at least ``IDR_MIN_INTERVAL_S`` ago: an IDR asked for now is granted at once, and one that
    follows was asked for by the test, not by a repeat."""
    if starts.pending:  # a start-point repeat still due
        return False
    with stage._lock:  # noqa: SLF001 - the rate limit's state is the point
        return (
            not stage._idr_pending  # noqa: SLF001
            and not stage._idr_again_at  # noqa: SLF001
            and stage._clock() - stage._last_idr_request >= IDR_MIN_INTERVAL_S  # noqa: SLF001
        )
