"""Token checks and guess throttling for the web console (ROS-free).

Every way of presenting the token (``Authorization: Bearer``, ``X-Axis-Token``, the ``axis_token`` cookie and the
login form) goes through one :class:`AuthThrottle` keyed by the client's address: at most ``max_failures`` wrong
tokens per ``window`` seconds; beyond that every request that presents a token from that address, right or
wrong, is answered 429 with ``Retry-After`` until the oldest counted failure leaves the window. A request that
presents no token at all is not a guess and is not counted (it gets the login page / 401).
"""

from __future__ import annotations

import hmac
import math
import threading
import time
from collections import deque

#: addresses remembered at most (oldest forgotten first); bounds memory under a flood of sources
MAX_CLIENTS = 4096


class AuthThrottle:
    """Per-address sliding window of failed token checks."""

    def __init__(self, max_failures: int = 5, window: float = 60.0) -> None:
        if max_failures < 1 or not (window > 0 and math.isfinite(window)):
            raise ValueError("auth throttle: max_failures must be >= 1 and window > 0 s")
        self.max_failures = max_failures
        self.window = window
        self._fails: dict[str, deque[float]] = {}
        self._lock = threading.Lock()

    def _trim(self, addr: str, now: float) -> deque[float] | None:
        q = self._fails.get(addr)
        if q is None:
            return None
        while q and now - q[0] >= self.window:
            q.popleft()
        if not q:
            del self._fails[addr]
            return None
        return q

    def retry_after(self, addr: str, now: float | None = None) -> float:
        """Seconds until ``addr`` may present a token again (0 = now)."""
        now = time.monotonic() if now is None else now
        with self._lock:
            q = self._trim(addr, now)
            if q is None or len(q) < self.max_failures:
                return 0.0
            return max(0.0, q[len(q) - self.max_failures] + self.window - now)

    def failed(self, addr: str, now: float | None = None) -> None:
        """Count one wrong token from ``addr``."""
        now = time.monotonic() if now is None else now
        with self._lock:
            q = self._trim(addr, now)
            if q is None:
                if len(self._fails) >= MAX_CLIENTS:
                    self._fails.pop(next(iter(self._fails)))
                q = self._fails[addr] = deque(maxlen=self.max_failures)
            q.append(now)

    def failures(self, addr: str) -> int:
        """Failures of ``addr`` still inside the window."""
        with self._lock:
            q = self._trim(addr, time.monotonic())
            return 0 if q is None else len(q)


def token_matches(presented: str, token: str) -> bool:
    """Constant-time comparison of a presented token with the configured one."""
    return hmac.compare_digest(presented.encode("utf-8"), token.encode("utf-8"))
