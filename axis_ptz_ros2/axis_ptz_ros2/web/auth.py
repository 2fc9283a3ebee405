"""Token checks and guess throttling for the web console (ROS-free).

Every way of presenting the token (``Authorization: Bearer``, ``X-Axis-Token``, the ``axis_token`` cookie and the
login form) goes through one :class:`AuthThrottle` keyed by the client's network (:func:`client_key`: all of
loopback is one client, an IPv6 address counts by its /64, an IPv4 address by itself), so rotating source
addresses on one machine or in one IPv6 prefix buys no fresh guesses: at most ``max_failures`` wrong tokens
per ``window`` seconds; beyond that every request that presents a token from that network, right or wrong, is
answered 429 with ``Retry-After`` until the oldest counted failure leaves the window. On top of that all
networks together get at most ``global_cap`` wrong tokens per window (many IPv4 sources at once). A request that
presents no token at all is not a guess and is not counted (it gets the login page / 401).
"""

from __future__ import annotations

import hmac
import ipaddress
import math
import os
import threading
import time
from collections import deque
from pathlib import Path

#: addresses remembered at most (oldest forgotten first); bounds memory under a flood of sources
MAX_CLIENTS = 4096
#: the cap on wrong tokens of all networks together per window, as a multiple of ``max_failures`` (at least 50)
GLOBAL_FACTOR = 10
_ALL = "*"


def client_key(addr: str) -> str:
    """The throttle's bucket of a client address: ``loopback``, the IPv6 /64, or the IPv4 address itself."""
    try:
        ip = ipaddress.ip_address(addr.split("%", 1)[0])
    except ValueError:
        return addr
    if isinstance(ip, ipaddress.IPv6Address) and ip.ipv4_mapped is not None:
        ip = ip.ipv4_mapped
    if ip.is_loopback:
        return "loopback"
    if isinstance(ip, ipaddress.IPv6Address):
        return str(ipaddress.IPv6Network((ip, 64), strict=False))
    return str(ip)


class AuthThrottle:
    """Per-network sliding window of failed token checks, with a cap on all networks together."""

    def __init__(self, max_failures: int = 5, window: float = 60.0, global_cap: int | None = None) -> None:
        """``max_failures`` per network and ``global_cap`` (default ``max(50, 10 × max_failures)``) per window."""
        if max_failures < 1 or not (window > 0 and math.isfinite(window)):
            raise ValueError("auth throttle: max_failures must be >= 1 and window > 0 s")
        self.max_failures = max_failures
        self.window = window
        self.global_cap = global_cap if global_cap is not None else max(50, GLOBAL_FACTOR * max_failures)
        if self.global_cap < max_failures:
            raise ValueError("auth throttle: global_cap must be >= max_failures")
        self._fails: dict[str, deque[float]] = {}
        self._all: deque[float] = deque(maxlen=self.global_cap)
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
            wait = 0.0
            while self._all and now - self._all[0] >= self.window:
                self._all.popleft()
            if len(self._all) >= self.global_cap:
                wait = self._all[0] + self.window - now
            q = self._trim(client_key(addr), now)
            if q is not None and len(q) >= self.max_failures:
                wait = max(wait, q[len(q) - self.max_failures] + self.window - now)
            return max(0.0, wait)

    def failed(self, addr: str, now: float | None = None) -> None:
        """Count one wrong token from ``addr``."""
        now = time.monotonic() if now is None else now
        key = client_key(addr)
        with self._lock:
            q = self._trim(key, now)
            if q is None:
                if len(self._fails) >= MAX_CLIENTS:
                    self._fails.pop(next(iter(self._fails)))
                q = self._fails[key] = deque(maxlen=self.max_failures)
            q.append(now)
            self._all.append(now)

    def failures(self, addr: str) -> int:
        """Failures of ``addr``'s network still inside the window."""
        with self._lock:
            q = self._trim(client_key(addr), time.monotonic())
            return 0 if q is None else len(q)


def token_matches(presented: str, token: str) -> bool:
    """Constant-time comparison of a presented token with the configured one."""
    return hmac.compare_digest(presented.encode("utf-8"), token.encode("utf-8"))


def load_token(path: str, env: str = "AXIS_WEB_TOKEN") -> str | None:
    """The access token: first line of the file ``path`` if given (ValueError when empty), else ``$env``."""
    if path:
        lines = Path(path).expanduser().read_text(encoding="utf-8").splitlines()
        tok = lines[0].strip() if lines else ""
        if not tok:
            raise ValueError("token_file is empty")
        return tok
    return os.environ.get(env) or None
