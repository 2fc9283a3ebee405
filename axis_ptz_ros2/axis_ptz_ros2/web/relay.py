"""The web console's video relay (ROS-free): the newest-frame slot of a JPEG stream, and the loop that writes one
stream to one HTTP client.

Video is passed through: the JPEG bytes of a ``CompressedImage`` go to every watching client unchanged, each client
always gets the newest frame (a slow client skips frames, nothing queues), and the owner of a slot is told when the
first client starts / the last client stops watching, so it subscribes to a topic only while it is watched. The
H.264 side of the same idea (access units, a GOP for late joiners, bounded per-client queues) is
:mod:`.h264relay`. :func:`relay` serves both to a client until the server stops or the client goes; the HTTP
routes and response heads are :mod:`.handler`'s.
"""

from __future__ import annotations

import select
import socket
import ssl
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from io import BufferedIOBase

from axis_ptz_ros2.vapix.mjpeg import part_header
from axis_ptz_ros2.web.h264relay import Client, H264Slot, encode_record

#: the multipart boundary of the console's MJPEG streams
BOUNDARY = "axisframe"
#: s, longest wait for the next frame of a stream before checking whether its client hung up
STREAM_POLL_S = 0.5

#: ``parts(timeout)``: the byte pieces of one client's next frame, or None when none came within ``timeout`` s
Parts = Callable[[float], tuple[bytes, ...] | None]


class FrameSlot:
    """The newest JPEG of one stream, shared by all HTTP clients; counts watchers.

    ``on_watchers`` is called (from an HTTP thread, outside the lock) whenever the watcher count goes
    0 → 1 or 1 → 0, so the owner can subscribe/unsubscribe.
    """

    def __init__(self, name: str, on_watchers: Callable[[str, int], None] | None = None) -> None:
        self.name = name
        self._cond = threading.Condition()
        self._seq = 0
        self._jpeg = b""
        self._arrival = 0.0
        self._watchers = 0
        self._on_watchers = on_watchers
        self._closed = False

    def publish(self, jpeg: bytes) -> None:
        """Store a new frame (bytes object kept as is: no copy, no re-encode) and wake the watchers."""
        with self._cond:
            self._seq += 1
            self._jpeg = jpeg
            self._arrival = time.monotonic()
            self._cond.notify_all()

    def latest(self) -> tuple[int, bytes, float]:
        """(sequence number, JPEG bytes, monotonic arrival time) of the newest frame (seq 0 = none yet)."""
        with self._cond:
            return self._seq, self._jpeg, self._arrival

    def wait_newer(self, seq: int, timeout: float) -> tuple[int, bytes] | None:
        """Block until a frame newer than ``seq`` exists (or timeout / close); return the newest one."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while self._seq <= seq and not self._closed:
                left = deadline - time.monotonic()
                if left <= 0:
                    return None
                self._cond.wait(left)
            if self._seq <= seq:
                return None
            return self._seq, self._jpeg

    @property
    def watchers(self) -> int:
        """HTTP clients currently watching this stream."""
        with self._cond:
            return self._watchers

    @contextmanager
    def watch(self) -> Iterator[None]:
        """Count one watcher for the duration of the ``with`` block."""
        with self._cond:
            self._watchers += 1
            n = self._watchers
        if n == 1 and self._on_watchers:
            self._on_watchers(self.name, n)
        try:
            yield
        finally:
            with self._cond:
                self._watchers -= 1
                n = self._watchers
            if n == 0 and self._on_watchers:
                self._on_watchers(self.name, n)

    def close(self) -> None:
        """Wake every waiter for good (server shutdown)."""
        with self._cond:
            self._closed = True
            self._cond.notify_all()


def jpeg_parts(slot: FrameSlot, boundary: str = BOUNDARY) -> Parts:
    """One client's MJPEG parts: each newer frame of ``slot`` as part header, JPEG, CRLF (frames in between are
    skipped). Call inside ``slot.watch()``."""
    seq = 0

    def parts(timeout: float) -> tuple[bytes, ...] | None:
        nonlocal seq
        got = slot.wait_newer(seq, timeout)
        if got is None:
            return None
        seq, jpeg = got
        return part_header(boundary, len(jpeg)), jpeg, b"\r\n"

    return parts


def h264_parts(slot: H264Slot, client: Client) -> Parts:
    """One client's H.264 records (:func:`.h264relay.encode_record`), ``client`` being what ``slot.watch()``
    gave."""

    def parts(timeout: float) -> tuple[bytes, ...] | None:
        got = slot.next(client, timeout)
        return None if got is None else (encode_record(got[0], catch_up=got[1]),)

    return parts


def relay(wfile: BufferedIOBase, conn: socket.socket, stop: threading.Event, parts: Parts) -> None:
    """Write what ``parts`` gives to ``wfile`` until ``stop`` is set or the client goes: a failed write, or a
    hang-up of ``conn`` noticed while no frame arrives (so idle streams end too)."""
    try:
        while not stop.is_set():
            pieces = parts(STREAM_POLL_S)
            if pieces is None:
                if client_gone(conn):
                    return
                continue
            for piece in pieces:
                wfile.write(piece)
            wfile.flush()
    except (OSError, ValueError):  # client went away (BrokenPipe, reset, timeout, closed file)
        return


def client_gone(conn: socket.socket) -> bool:
    """True when the client closed its end of ``conn`` (plain or TLS); never blocks."""
    try:
        if isinstance(conn, ssl.SSLSocket):
            if not conn.pending() and not _readable(conn):
                return False
            old = conn.gettimeout()
            conn.settimeout(0.0)
            try:
                return conn.recv(1) == b""  # TLS records (close_notify, key update) or EOF
            except (ssl.SSLWantReadError, ssl.SSLWantWriteError):
                return False
            finally:
                conn.settimeout(old)
        if not _readable(conn):
            return False
        return bool(conn.recv(1, socket.MSG_PEEK) == b"")
    except (OSError, ValueError):
        return True


def _readable(conn: socket.socket) -> bool:
    """Whether ``conn`` has something to read (data, EOF or an error) right now."""
    readable, _, _ = select.select([conn], [], [], 0)
    return bool(readable)
