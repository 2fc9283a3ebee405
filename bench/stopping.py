"""How a bench's simulator child runs until it is told to stop: the one place for the SIGTERM/SIGINT wait of
``pipelines.sim_child`` and ``capture_match.sim_child``. The parent stops a child with SIGINT (``pipelines.Proc``) or
SIGTERM. (The ROS viewers spin with ``tests/support/spin.spin_until_stopped``, shared with the tests' link probe.)"""

from __future__ import annotations

import signal
import threading


def wait_for_stop() -> None:
    """Block until this process gets SIGTERM or SIGINT (replaces their handlers)."""
    done = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: done.set())
    signal.signal(signal.SIGINT, lambda *_: done.set())
    done.wait()
