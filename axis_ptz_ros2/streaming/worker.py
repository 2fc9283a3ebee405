"""One managed thread of a streaming component (the MJPEG reader, the RTSP source, discovery). ROS-free.

Started once; stopped with a flag the thread's loop checks, an optional ``interrupt()`` that closes what the
thread blocks on (a socket, a session), and a bounded join.
"""

from __future__ import annotations

import threading
from collections.abc import Callable


class Worker:
    """A named daemon thread running ``run`` (see the module docstring); :attr:`stopping` is its stop flag."""

    def __init__(
        self, what: str, name: str, run: Callable[[], None], interrupt: Callable[[], None] | None = None
    ) -> None:
        """``what``: the component, for the refusal of a second start; ``name``: the thread's name."""
        self._what = what
        self._name = name
        self._run = run
        self._interrupt = interrupt
        self.stopping = threading.Event()
        self._thread: threading.Thread | None = None

    @property
    def started(self) -> bool:
        """Whether :meth:`start` was called."""
        return self._thread is not None

    def start(self) -> None:
        """Start the thread (once; a second start raises RuntimeError)."""
        if self._thread is not None:
            raise RuntimeError(f"{self._what} already started")
        self._thread = threading.Thread(target=self._run, name=self._name, daemon=True)
        self._thread.start()

    def stop(self, timeout: float) -> bool:
        """Set the stop flag, interrupt, join; False if the thread did not end within ``timeout`` s."""
        self.stopping.set()
        if self._interrupt is not None:
            self._interrupt()
        thread = self._thread
        if thread is None:
            return True
        thread.join(timeout)
        return not thread.is_alive()
