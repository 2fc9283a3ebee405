"""Giving the C heap's free pages back to the operating system (ROS-free).

Why: a driver runs for days, and its frames are large buffers of changing sizes (a JPEG of 20–200 kB, thirty a
second, its size following the scene, the zoom and the fps). glibc's allocator serves them from per-thread
arenas whose free pages it returns to the system only at an arena's top, so the resident set creeps up with
fragmentation though nothing leaks. Measured on the soak bench (bench/bench_soak.py, a camera reboot every
minute): Python's own heap stayed flat under ``tracemalloc`` across reboots, ``MALLOC_ARENA_MAX=2`` changed
nothing, and the growth was one thread arena's resident pages (1.7 → 3.9 MB in ten minutes, from
``/proc/<pid>/smaps``). ``malloc_trim(0)`` releases the free pages inside every arena (``madvise``), which is
what :func:`release_free_memory` calls; the runner calls it every :data:`TRIM_PERIOD_S` seconds.

Elsewhere (another C library) this is a no-op that says so.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
from collections.abc import Callable

TRIM_PERIOD_S = 30.0  #: how often the runner gives free heap pages back (a call costs well under a millisecond)


@functools.cache
def _malloc_trim() -> Callable[[int], int] | None:
    name = ctypes.util.find_library("c")
    if name is None:
        return None
    try:
        fn = ctypes.CDLL(name).malloc_trim
    except (OSError, AttributeError):  # not glibc (musl, macOS): nothing to call
        return None
    fn.argtypes = [ctypes.c_size_t]
    fn.restype = ctypes.c_int
    return fn


def can_release() -> bool:
    """Whether this C library has ``malloc_trim`` (glibc)."""
    return _malloc_trim() is not None


def release_free_memory() -> bool:
    """``malloc_trim(0)``: True if memory was given back, False if none could be (or no glibc)."""
    fn = _malloc_trim()
    return bool(fn(0)) if fn is not None else False
