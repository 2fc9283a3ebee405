"""Waiting for the link adapter to climb, with its judgements in the failure message.

A climb needs report windows the adapter judges *clear* (a short queue, the bytes delivered); on a machine that
pauses the whole test process (a loaded CI host, the garbage collector) loopback itself reads as a queue, and
the adapter rightly holds. A timed-out climb therefore says what the adapter saw: how often it judged each
state and the queueing delays it measured, so a defect can be told from a host that was not quiet.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable
from typing import Any

from tests.support.harness import RosHarness


def wait_for_climb(ros: RosHarness, node: Any, reached: Callable[[], bool], timeout: float) -> None:  # noqa: ANN401
    """``ros.wait_for(reached, timeout)``, sampling ``node._video.state()`` (a ``StreamNode``) meanwhile; on a
    timeout the AssertionError lists the link states and queueing delays seen."""
    states: Counter[str] = Counter()
    delays: list[float] = []

    def check() -> bool:
        s = node._video.state()  # noqa: SLF001
        states[s.link_state] += 1
        if not math.isnan(s.link_queue_delay_s):
            delays.append(s.link_queue_delay_s)
        return reached()

    try:
        ros.wait_for(check, timeout=timeout, period=0.05)
    except AssertionError as err:
        total = sum(states.values()) or 1
        seen = ", ".join(f"{k} {100 * n / total:.0f} %" for k, n in states.most_common())
        q = sorted(delays)
        queue = f"queue delay median {1000 * q[len(q) // 2]:.0f} ms, max {1000 * q[-1]:.0f} ms" if q else "no delay"
        budget = node._video.state().link_budget_kbps  # noqa: SLF001
        why = f"link adapter meanwhile: {seen}; {queue}; budget now {budget:.0f} kbit/s"
        raise AssertionError(f"{err}; {why}") from None
