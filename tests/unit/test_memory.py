"""memory.release_free_memory gives the free pages inside a fragmented heap back (glibc's malloc_trim)."""

from __future__ import annotations

import threading

import pytest

from axis_ptz_ros2 import memory

pytestmark = pytest.mark.skipif(not memory.can_release(), reason="no malloc_trim in this C library (not glibc)")


def rss_kb() -> int:
    with open("/proc/self/status", encoding="ascii") as f:
        return next(int(line.split()[1]) for line in f if line.startswith("VmRSS:"))


def test_free_pages_between_live_buffers_are_given_back() -> None:
    """A thread allocates 400 frame-sized buffers (96 kB: below glibc's mmap threshold, so from its arena), keeps
    every tenth and frees the rest: the holes stay resident until the trim, which gives most of them back."""
    kept: list[bytearray] = []
    result: dict[str, int] = {}

    def work() -> None:
        bufs = [bytearray(b"\x01" * (96 << 10)) for _ in range(400)]  # touched: resident
        kept.extend(bufs[::10])
        del bufs
        result["before"] = rss_kb()
        assert memory.release_free_memory()
        result["after"] = rss_kb()

    t = threading.Thread(target=work)
    t.start()
    t.join()
    freed = 360 * 96  # kB in the holes
    assert result["before"] - result["after"] >= freed // 2, result
    assert len(kept) == 40
