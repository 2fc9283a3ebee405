"""What the simulated camera was asked: request counters and logs, for tests and benchmarks (ROS-free)."""

from __future__ import annotations

import collections
import copy
import threading
import time
from dataclasses import dataclass, field
from typing import Any


@dataclass
class PtzLogEntry:
    """One received ``ptz.cgi`` request."""

    t_wall: float
    t_mono: float
    method: str
    query: str


@dataclass
class RequestCounts:
    """Requests seen by the simulator: per endpoint, per PTZ command kind, and a log of PTZ queries."""

    endpoints: collections.Counter[str] = field(default_factory=collections.Counter)
    ptz: collections.Counter[str] = field(default_factory=collections.Counter)
    ptz_log: list[PtzLogEntry] = field(default_factory=list)
    video_log: list[PtzLogEntry] = field(default_factory=list)  #: video.cgi / image.cgi requests (query strings)
    status: collections.Counter[int] = field(default_factory=collections.Counter)
    auth: collections.Counter[str] = field(default_factory=collections.Counter)  #: Authorization scheme seen

    def as_dict(self) -> dict[str, Any]:
        """JSON-friendly mapping."""
        return {
            "endpoints": dict(self.endpoints),
            "ptz": dict(self.ptz),
            "status": {str(k): v for k, v in self.status.items()},
            "auth": dict(self.auth),
            "ptz_log": [[e.t_wall, e.method, e.query] for e in self.ptz_log[-200:]],
            "video_log": [[e.t_wall, e.method, e.query] for e in self.video_log[-200:]],
        }


class RequestLog:
    """:class:`RequestCounts` behind a lock: every listener records into it, readers get copies."""

    def __init__(self) -> None:
        """Empty."""
        self._counts = RequestCounts()
        self._lock = threading.Lock()

    def snapshot(self) -> RequestCounts:
        """A deep copy of the counters and logs."""
        with self._lock:
            return copy.deepcopy(self._counts)

    def as_dict(self) -> dict[str, Any]:
        """The counters as JSON-friendly mapping."""
        with self._lock:
            return self._counts.as_dict()

    def reset(self) -> None:
        """Clear the counters and logs."""
        with self._lock:
            self._counts = RequestCounts()

    def count(self, endpoint: str, status: int | None = None) -> None:
        """One request to ``endpoint`` ("" = none) and/or one reply with ``status``."""
        with self._lock:
            if endpoint:
                self._counts.endpoints[endpoint] += 1
            if status is not None:
                self._counts.status[status] += 1

    def count_auth(self, authorization: str | None) -> None:
        """The scheme of an ``Authorization`` header (``none`` without one)."""
        with self._lock:
            self._counts.auth[authorization.split(" ", 1)[0].lower() if authorization else "none"] += 1

    def log_ptz(self, method: str, query: str, args: list[tuple[str, str]]) -> None:
        """A PTZ request: logged, and counted per command (``query=…`` and ``move=…`` per value)."""
        with self._lock:
            self._counts.ptz_log.append(PtzLogEntry(time.time(), time.monotonic(), method, query))
            if len(self._counts.ptz_log) > 100000:
                del self._counts.ptz_log[:50000]
            for k, v in args:
                kl = k.lower()
                self._counts.ptz[f"{kl}={v}" if kl in ("query", "move") else kl] += 1

    def ptz_log_since(self, seen: int) -> tuple[list[PtzLogEntry], int]:
        """PTZ requests logged after the first ``seen`` (all of them if the log was cleared or trimmed since), and
        the new count to pass next time: a reader follows the log without copying all of it."""
        with self._lock:
            log = self._counts.ptz_log
            if len(log) < seen:
                seen = 0
            return log[seen:], len(log)

    def log_video(self, method: str, query: str) -> None:
        """A video or snapshot request (what the camera was asked for: tests check "the camera never saw it")."""
        with self._lock:
            self._counts.video_log.append(PtzLogEntry(time.time(), time.monotonic(), method, query))
            del self._counts.video_log[:-10000]
