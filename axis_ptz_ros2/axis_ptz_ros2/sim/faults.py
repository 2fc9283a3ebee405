"""Fault injection for the simulated camera, and the black hole a packet-dropping reboot opens (ROS-free).

Every field defaults to "off". Set them at construction (``SimulatedCamera(faults=FaultConfig(...))``), at run
time (``camera.set_faults(stall_after_frames=10)``), from the CLI (``--fault-stall-after-frames 10``) or over
HTTP from another process (``GET /sim/control?stall_after_frames=10&stall_seconds=2``).
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import socket
import threading
import time
from dataclasses import dataclass
from typing import Any

HTTP_ERROR_CODES = (401, 500, 503)
HTTP_ERROR_SCOPES = ("all", "video")
REBOOT_ERROR_KINDS = ("503", "empty", "401")  #: what the web server answers in the last phase of a reboot


@dataclass(frozen=True, slots=True)
class FaultConfig:
    """Faults of the simulated camera. Frame counts are per MJPEG connection (0 = never)."""

    drop_after_frames: int = 0  #: close the stream (mid-part) after this many frames
    stall_after_frames: int = 0  #: stop sending (socket stays open) after this many frames …
    stall_seconds: float = 0.0  #: … for this long, then continue
    garbage_between_parts: bool = False  #: random bytes between a part's trailing CRLF and the next boundary
    truncate_every: int = 0  #: every Nth frame is a truncated JPEG (Content-Length matches the cut length)
    wrong_length_every: int = 0  #: every Nth part announces a wrong Content-Length …
    wrong_length_delta: int = 100  #: … off by this many bytes
    http_error: int = 0  #: answer with this status (401, 500 or 503) …
    http_error_scope: str = "all"  #: … on "all" camera endpoints or only on "video" (video.cgi, image.cgi)
    latency_ms: float = 0.0  #: added delay before every reply; video frames are delivered this late
    bandwidth_kbps: float = 0.0  #: cap on the bytes sent per connection (kbit/s), 0 = unlimited
    no_imagesize: bool = False  #: imagesize.cgi answers 404, as on firmware without it (issue 23)
    clock_offset_s: float = 0.0  #: the camera's wall clock minus the true time (a camera without NTP): the RTCP
    #: sender reports carry it, the RTP clock does not move; the SEI capture stamp stays the true time (ground truth)

    def __post_init__(self) -> None:
        """Validate."""
        for name in ("drop_after_frames", "stall_after_frames", "truncate_every", "wrong_length_every"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be >= 0")
        if not math.isfinite(self.clock_offset_s):
            raise ValueError("clock_offset_s must be finite (seconds)")
        if self.stall_seconds < 0 or self.latency_ms < 0 or self.bandwidth_kbps < 0:
            raise ValueError("stall_seconds, latency_ms and bandwidth_kbps must be >= 0")
        if self.http_error not in (0, *HTTP_ERROR_CODES):
            raise ValueError(f"http_error must be 0 or one of {HTTP_ERROR_CODES}")
        if self.http_error_scope not in HTTP_ERROR_SCOPES:
            raise ValueError(f"http_error_scope must be one of {HTTP_ERROR_SCOPES}")

    def replace(self, **changes: Any) -> FaultConfig:
        """A copy with ``changes`` applied (values may be strings, as from a query string)."""
        types = {f.name: f.type for f in dataclasses.fields(self)}
        conv: dict[str, Any] = {}
        for k, v in changes.items():
            if k not in types:
                raise ValueError(f"unknown fault {k!r}")
            t = types[k]
            if isinstance(v, str):
                if t in ("bool", bool):
                    conv[k] = v.lower() in ("1", "true", "yes", "on")
                elif t in ("int", int):
                    conv[k] = int(v)
                elif t in ("float", float):
                    conv[k] = float(v)
                else:
                    conv[k] = v
            else:
                conv[k] = v
        return dataclasses.replace(self, **conv)

    def as_dict(self) -> dict[str, Any]:
        """Plain mapping (for ``/sim/state``)."""
        return dataclasses.asdict(self)

    @staticmethod
    def field_names() -> list[str]:
        """Names of all faults."""
        return [f.name for f in dataclasses.fields(FaultConfig)]


class Blackhole:
    """A camera that drops packets (a reboot on a real network): connects hang, open connections go mute.

    :meth:`mute` first (streams and held requests watch :attr:`active` and stop answering), then :meth:`hold` the
    camera's ports with listeners that never accept and whose (tiny) accept queues are full: the kernel then
    drops every new SYN, so a client's connect hangs as if the camera were off the network. :meth:`end` releases
    the ports; held requests then end with a reset, as for a peer that rebooted.
    """

    def __init__(self) -> None:
        """Inactive."""
        self._active = threading.Event()
        self._socks: list[socket.socket] = []

    @property
    def active(self) -> bool:
        """Whether the camera drops packets now."""
        return self._active.is_set()

    def mute(self) -> None:
        """Go mute (before the listeners close: streams must fall silent, not close)."""
        self._active.set()

    def hold(self, host: str, ports: list[int]) -> None:
        """Hold ``ports`` on ``host`` so that connects hang."""
        family = socket.AF_INET6 if ":" in host else socket.AF_INET
        for port in ports:
            listener = socket.socket(family, socket.SOCK_STREAM)
            listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            for _ in range(100):
                try:
                    listener.bind((host, port))
                    break
                except OSError:
                    time.sleep(0.02)
            listener.listen(0)
            socks = [listener]
            for _ in range(4):
                filler = socket.socket(family, socket.SOCK_STREAM)
                filler.setblocking(False)
                filler.connect_ex((host, port))
                socks.append(filler)
            self._socks.extend(socks)

    def end(self) -> None:
        """Release the ports and answer again."""
        socks, self._socks = self._socks, []
        for sock in socks:
            with contextlib.suppress(OSError):
                sock.close()
        self._active.clear()  # held requests now end with a reset, as for a peer that rebooted
