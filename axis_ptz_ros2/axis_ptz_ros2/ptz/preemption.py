"""Latest-wins bookkeeping of long-running goals (ROS-free): starting a goal pre-empts the one running."""

from __future__ import annotations

import threading


class Preemption:
    """Latest-wins bookkeeping of long-running goals: starting a goal pre-empts the one running (ROS-free)."""

    def __init__(self) -> None:
        """No goal running."""
        self._lock = threading.Lock()
        self._current: bytes | None = None
        self._preempted: set[bytes] = set()

    def start(self, key: bytes) -> None:
        """``key`` becomes the running goal; the previous one (if any) is pre-empted."""
        with self._lock:
            if self._current is not None and self._current != key:
                self._preempted.add(self._current)
            self._current = key

    def preempted(self, key: bytes) -> bool:
        """Whether a newer goal pre-empted ``key``."""
        with self._lock:
            return key in self._preempted

    def finish(self, key: bytes) -> None:
        """``key`` ended."""
        with self._lock:
            self._preempted.discard(key)
            if self._current == key:
                self._current = None
