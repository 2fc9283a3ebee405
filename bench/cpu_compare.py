"""The judged CPU comparison of two pipelines (``axis_stream`` against ``bench/minimal_pipeline.py``): both streaming
to a subscriber over shared wall-clock windows, in both start orders (README, "How CPU is compared"). Used by
``bench_stream`` and ``bench_stream_1080p``."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

from pipelines import Proc, Subscriber, subscribed, wait_until


def measure_cpu_side_by_side(
    sub: Subscriber, ours: Proc, mini: Proc, seconds: float, repeats: int
) -> list[tuple[float, float]]:
    """CPU of both pipelines, each streaming to a subscriber, over the same wall-clock windows.

    Windows taken one after the other (as ``measure_load`` does) see different machine load and different
    moments of each process's life; sharing the window cancels both, so the ratio is what is judged.
    """
    with subscribed(sub, "/ours") as r_ours, subscribed(sub, "/minimal") as r_min:
        if not wait_until(lambda: len(r_ours.frames) >= 10 and len(r_min.frames) >= 10, 10.0):
            raise RuntimeError("side by side: no frames")
        time.sleep(1.5)  # warm-up
        out = []
        for _ in range(repeats):
            o0, m0, t0 = ours.cpu_s(), mini.cpu_s(), time.monotonic()
            time.sleep(seconds)
            dt = time.monotonic() - t0
            out.append((100.0 * (ours.cpu_s() - o0) / dt, 100.0 * (mini.cpu_s() - m0) / dt))
    return out


def side_by_side_median(side: list[tuple[float, float]]) -> tuple[float, float, float]:
    """(ours, minimal, ratio) of the window with the median ratio."""
    o, m = sorted(side, key=lambda w: w[0] / w[1])[len(side) // 2]
    return o, m, o / m


SHARED_WINDOWS = "3 shared windows each, a simulator per pipeline"


@dataclass
class CpuComparison:
    """:func:`measure_cpu_both_orders`: the shared windows of each start order and the judged ratio."""

    ours_first: list[tuple[float, float]]
    minimal_first: list[tuple[float, float]]

    @property
    def ratio(self) -> float:
        """Geometric mean of the two orders' median ratios: a cost of being started first cancels out."""
        return math.sqrt(side_by_side_median(self.ours_first)[2] * side_by_side_median(self.minimal_first)[2])

    @property
    def cpu(self) -> tuple[float, float]:
        """(ours, minimal) % of a core, the mean of both orders' median windows."""
        a, b = side_by_side_median(self.ours_first), side_by_side_median(self.minimal_first)
        return (a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0

    def describe(self) -> str:
        def one(side: list[tuple[float, float]]) -> str:
            return ", ".join(f"{o:.2f} vs {m:.2f} % ({o / m:.2f}x)" for o, m in side)

        return f"axis_stream started first: {one(self.ours_first)}; minimal first: {one(self.minimal_first)}"


def measure_cpu_both_orders(
    sub: Subscriber,
    start_ours_fn: Callable[[], Proc],
    start_minimal_fn: Callable[[], Proc],
    seconds: float,
    repeats: int = 3,
) -> CpuComparison:
    """The judged CPU comparison: each pipeline on a simulator of its own (the caller's starters), side by side
    over shared windows (:func:`measure_cpu_side_by_side`), once started ours-first and once minimal-first.

    Two *identical* pipelines side by side do not cost the same: the one started first cost 16 % more on one
    simulator and 6 % more with one simulator each (two minimal pipelines, 30 s windows of the scheduler's run
    time, 8868dbf). With one fixed order that bias is the size of the target's margin, so both orders are
    measured and their ratios averaged (geometric mean)."""
    rounds: list[list[tuple[float, float]]] = []
    for ours_first in (True, False):
        procs: list[Proc] = []
        try:
            for which in ("ours", "minimal") if ours_first else ("minimal", "ours"):
                procs.append(start_ours_fn() if which == "ours" else start_minimal_fn())
                if which == "ours":
                    sub.call_ready("/ours/video/set_params")
                time.sleep(1.0)
            ours = procs[0] if ours_first else procs[1]
            mini = procs[1] if ours_first else procs[0]
            rounds.append(measure_cpu_side_by_side(sub, ours, mini, seconds, repeats))
        finally:
            for proc in procs:
                proc.stop()
    return CpuComparison(rounds[0], rounds[1])
