"""What the offline CPU benches (``bench_transcode``, ``encoder_tradeoff``) read of this process and the machine:
the process's own CPU seconds and the load average printed beside their figures (on a shared machine the
figures carry some of the other processes' load)."""

from __future__ import annotations

import resource


def cpu_s() -> float:
    """User + system CPU seconds of this process, all threads (libx264 may use several)."""
    ru = resource.getrusage(resource.RUSAGE_SELF)
    return ru.ru_utime + ru.ru_stime


def loadavg() -> str:
    """The machine's 1, 5 and 15 minute load averages as ``/proc/loadavg`` gives them."""
    with open("/proc/loadavg", encoding="ascii") as f:
        return " ".join(f.read().split()[:3])
