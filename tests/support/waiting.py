"""Waiting for a condition instead of sleeping a fixed time (test and bench tooling, ROS-free).

Every test that needs something to have happened polls for it with :func:`wait_until`; a fixed ``time.sleep`` is
left only where the time itself is the thing under test (nothing may happen within a window, a timeout must
pass, a load must be paced) and then carries a comment saying so (``tests/unit/test_sleeps_budget.py`` counts them).
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from typing import Any

#: Multiplier of every scaled deadline (conditions are awaited, not timed): a loaded machine only slows a run down.
DEADLINE_SCALE = float(os.environ.get("AXIS_TEST_DEADLINE_SCALE", "4"))


def wait_until(
    predicate: Callable[[], Any],
    timeout: float = 10.0,
    interval: float = 0.01,
    *,
    what: str = "",
    scaled: bool = True,
    raises: bool = True,
    tick: Callable[[], None] | None = None,
) -> Any:
    """Poll ``predicate()`` every ``interval`` s until it is truthy and return its value.

    ``timeout`` is a deadline for the condition, never a speed bound: unless ``scaled=False`` it is multiplied by
    ``AXIS_TEST_DEADLINE_SCALE`` (default 4). On timeout raise AssertionError naming ``what`` (or the predicate),
    or, with ``raises=False``, return the predicate's last (falsy) value. ``tick`` runs before each pause (e.g. to
    check that helper processes are still alive, so a crash fails at once rather than at the deadline).
    """
    if timeout < 0 or interval <= 0:
        raise ValueError(f"wait_until: timeout must be >= 0 and interval > 0 (got {timeout!r}, {interval!r})")
    if scaled:
        timeout *= DEADLINE_SCALE
    deadline = time.monotonic() + timeout
    while True:
        v = predicate()
        if v:
            return v
        if time.monotonic() >= deadline:
            break
        if tick is not None:
            tick()
        time.sleep(min(interval, max(0.0, deadline - time.monotonic())))
    if not raises:
        return v
    raise AssertionError(f"timed out after {timeout:.1f} s waiting for {what or predicate}")


def succeeds(call: Callable[[], Any], *errors: type[BaseException]) -> Callable[[], bool]:
    """A predicate for :func:`wait_until`: True once ``call()`` returns without raising one of ``errors`` (any
    other exception propagates)."""

    def attempt() -> bool:
        try:
            call()
        except errors:
            return False
        return True

    return attempt


def unchanged_for(value: Callable[[], Any], seconds: float) -> Callable[[], bool]:
    """A predicate for :func:`wait_until`: True once ``value()`` has stayed the same for ``seconds`` (a quiet
    period: nothing was sent, nothing was rebuilt), judged at each poll; any change starts the period again."""
    state: dict[str, Any] = {"since": None, "value": None}

    def quiet() -> bool:
        v, now = value(), time.monotonic()
        if state["since"] is None or v != state["value"]:
            state["since"], state["value"] = now, v
            return False
        return bool(now - state["since"] >= seconds)

    return quiet
