"""One managed thread of a streaming component (the MJPEG reader, the RTSP source, discovery). ROS-free.

Started once; stopped with a flag the thread's loop checks, an optional ``interrupt()`` that closes what the
thread blocks on (a socket, a session), and a bounded join. Lazy components switch it on and off with
:meth:`Worker.set_active` (the thread idles while it is off).
"""

from __future__ import annotations

import threading
from collections.abc import Callable


class Worker:
    """A named daemon thread running ``run`` (see the module docstring); :attr:`stopping` is its stop flag."""

    def __init__(
        self,
        what: str,
        name: str,
        run: Callable[[], None],
        interrupt: Callable[[], None] | None = None,
        *,
        active: bool = True,
    ) -> None:
        """``what``: the component, for the refusal of a second start; ``name``: the thread's name; ``active``:
        whether it is to work from the start."""
        self._what = what
        self._name = name
        self._run = run
        self._interrupt = interrupt
        self.stopping = threading.Event()
        self._thread: threading.Thread | None = None
        self._active = active
        self._active_lock = threading.Lock()

    @property
    def active(self) -> bool:
        """Whether the component is to work (``run`` idles while it is not)."""
        return self._active

    def set_active(self, active: bool) -> None:
        """Switch :attr:`active`; a change interrupts the thread (it wakes, and what it blocks on is closed).

        The flag is set before ``interrupt()`` runs: a thread that reads it before taking what it will block on
        (under the lock ``interrupt()`` also takes) either sees the new value or has that taken thing closed."""
        with self._active_lock:
            if active == self._active:
                return
            self._active = active
        if self._interrupt is not None:
            self._interrupt()

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
