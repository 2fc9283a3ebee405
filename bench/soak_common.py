"""What the soaks (``bench_soak``, ``bench_soak_h264``) sample of a process and how they judge it: RSS, threads and
open file descriptors from ``/proc``, and the least-squares RSS slope over the second half of the run (the first
half holds the start-up's allocations and the caches filling)."""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

SAMPLE_EVERY_S = 10.0  #: seconds between two samples of a soaked process


def fd_count(pid: int) -> int:
    """Open file descriptors of process ``pid``."""
    return len(os.listdir(f"/proc/{pid}/fd"))


def status(pid: int, key: str) -> int:
    """A number from ``/proc/<pid>/status`` (``Threads``, ``VmRSS`` in kB …); -1 when the key is absent."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith(key + ":"):
            return int(line.split()[1])
    return -1


def sample(pid: int, t: float) -> tuple[float, float, int, int]:
    """``(t, RSS MB, threads, fds)`` of process ``pid`` now (``t``: the run's clock, s)."""
    return t, status(pid, "VmRSS") / 1024.0, status(pid, "Threads"), fd_count(pid)


def second_half(samples: list[tuple[float, float, int, int]]) -> list[tuple[float, float, int, int]]:
    """The samples from the middle of the run on."""
    return [s for s in samples if s[0] >= samples[-1][0] / 2.0] if samples else []


def rss_slope_mb_per_h(samples: list[tuple[float, float, int, int]]) -> float:
    """Least-squares slope of RSS (MB per hour) over the second half; NaN with fewer than 3 samples there."""
    half = second_half(samples)
    if len(half) < 3:
        return math.nan
    t = np.array([s[0] for s in half]) / 3600.0
    rss = np.array([s[1] for s in half])
    return float(np.polyfit(t, rss, 1)[0])


def ranges(samples: list[tuple[float, float, int, int]]) -> tuple[tuple[int, int], tuple[int, int]]:
    """``((threads min, max), (fds min, max))`` over the second half."""
    half = second_half(samples)
    return (min(s[2] for s in half), max(s[2] for s in half)), (min(s[3] for s in half), max(s[3] for s in half))
