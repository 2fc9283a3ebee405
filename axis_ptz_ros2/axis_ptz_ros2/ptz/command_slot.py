"""Latest-wins command slot: at most one camera request in flight, newer motion replaces pending motion.

A teleop or tracker can publish set-points far faster than a PTZ camera answers HTTP requests. Queueing them
would make the head lag further and further behind; dropping the newest would lose the operator's intent.
:class:`CommandSlot` runs one worker thread that executes one command at a time. A *supersedable* command (any
motion: absolute, velocity, stop, home, preset goto) submitted while another supersedable command is still
waiting replaces it (the replaced ticket ends ``SUPERSEDED``); non-supersedable commands (store or remove a
preset) are never dropped and keep their order. So a burst ends with exactly the last command sent, within one
round trip of its submission. ROS-free.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import StrEnum


class Outcome(StrEnum):
    """How a submitted command ended."""

    PENDING = "pending"
    SENT = "sent"  # the request completed successfully
    FAILED = "failed"  # the request raised; ``error`` says why
    SUPERSEDED = "superseded"  # a newer command replaced it before it was sent
    CANCELLED = "cancelled"  # the slot stopped first


@dataclass(eq=False)
class Ticket:
    """Handle of one submitted command."""

    label: str
    supersedable: bool
    submitted_ns: int = field(default_factory=time.monotonic_ns)
    started_ns: int = 0
    finished_ns: int = 0
    outcome: Outcome = Outcome.PENDING
    error: str = ""
    _done: threading.Event = field(default_factory=threading.Event, repr=False)

    def wait(self, timeout: float | None = None) -> bool:
        """Block until the command ended (sent, failed, superseded or cancelled); False on timeout."""
        return self._done.wait(timeout)

    @property
    def done(self) -> bool:
        """Whether the command has ended."""
        return self._done.is_set()

    def _finish(self, outcome: Outcome, error: str = "") -> None:
        self.outcome = outcome
        self.error = error
        self.finished_ns = time.monotonic_ns()
        self._done.set()


@dataclass
class SlotStats:
    """Counters (monotonic) of a :class:`CommandSlot`."""

    submitted: int = 0
    sent: int = 0
    failed: int = 0
    superseded: int = 0
    last_error: str = ""
    last_latency_s: float = 0.0  # submission -> request completed, of the last sent command


class CommandSlot:
    """One worker thread executing submitted callables one at a time, latest motion wins."""

    def __init__(
        self,
        name: str = "ptz-commands",
        error_types: tuple[type[BaseException], ...] = (Exception,),
        on_error: Callable[[Ticket, BaseException], None] | None = None,
    ) -> None:
        """``error_types``: exceptions a command may raise that mark its ticket FAILED. Any other exception is a
        defect: its ticket fails with "internal error: …" and the worker lives on (a dead worker would leave every
        later command waiting). ``on_error`` is called (from the worker) for each failure."""
        self._name = name
        self._error_types = error_types
        self._on_error = on_error
        self._cond = threading.Condition()
        self._queue: deque[tuple[Ticket, Callable[[], None]]] = deque()
        self._stop = threading.Event()
        self._busy = False
        self._thread: threading.Thread | None = None
        self.stats = SlotStats()

    def start(self) -> None:
        """Start the worker thread."""
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name=self._name, daemon=True)
            self._thread.start()

    def submit(self, label: str, fn: Callable[[], None], *, supersedable: bool = True) -> Ticket:
        """Queue ``fn``; a supersedable one replaces every pending supersedable command."""
        ticket = Ticket(label, supersedable)
        with self._cond:
            if self._stop.is_set():
                ticket._finish(Outcome.CANCELLED, "command slot stopped")
                return ticket
            self.stats.submitted += 1
            if supersedable and self._queue:
                kept: deque[tuple[Ticket, Callable[[], None]]] = deque()
                for t, f in self._queue:
                    if t.supersedable:
                        self.stats.superseded += 1
                        t._finish(Outcome.SUPERSEDED, f"replaced by {label}")
                    else:
                        kept.append((t, f))
                self._queue = kept
            self._queue.append((ticket, fn))
            self._cond.notify()
        return ticket

    @property
    def idle(self) -> bool:
        """Nothing pending and nothing in flight."""
        with self._cond:
            return not self._queue and not self._busy

    def _run(self) -> None:
        while True:
            with self._cond:
                while not self._queue and not self._stop.is_set():
                    self._cond.wait()
                if self._stop.is_set():
                    return
                ticket, fn = self._queue.popleft()
                self._busy = True
            ticket.started_ns = time.monotonic_ns()
            try:
                fn()
            except self._error_types as err:
                with self._cond:
                    self.stats.failed += 1
                    self.stats.last_error = str(err)
                    self._busy = False
                ticket._finish(Outcome.FAILED, str(err))
                if self._on_error is not None:
                    self._on_error(ticket, err)
            except Exception as err:  # noqa: BLE001 - a defect in one command must not end the worker
                # (found by the ROS-input fuzz tier: a speed of 1e308 overflowed while the request was built, the
                # exception ended this thread and every later command waited forever for it)
                with self._cond:
                    self.stats.failed += 1
                    self.stats.last_error = f"internal error: {type(err).__name__}: {err}"
                    self._busy = False
                ticket._finish(Outcome.FAILED, f"internal error: {type(err).__name__}: {err}")
                if self._on_error is not None:
                    self._on_error(ticket, err)
            else:
                with self._cond:
                    self.stats.sent += 1
                    self._busy = False
                ticket._finish(Outcome.SENT)
                self.stats.last_latency_s = (ticket.finished_ns - ticket.submitted_ns) / 1e9

    def stop(self, timeout: float = 5.0) -> None:
        """Cancel pending commands, let the one in flight finish (up to ``timeout``) and join the worker."""
        with self._cond:
            self._stop.set()
            for t, _ in self._queue:
                t._finish(Outcome.CANCELLED, "command slot stopped")
            self._queue.clear()
            self._cond.notify_all()
        if self._thread is not None:
            self._thread.join(timeout)
            self._thread = None
