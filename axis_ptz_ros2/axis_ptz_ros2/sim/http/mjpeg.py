"""The simulated camera's Motion-JPEG stream, ``video.cgi`` (vapix.md §5.1), with its stream faults (ROS-free).

Paced at the requested ``fps``, at most the persona's ``frame_rate`` (the PAL 214: 25 pictures a second; ``fps=0``:
as fast as possible, the latest picture sent again between new ones, a test mode: see the README), ``duration`` and
``nbrofframes`` honoured, frames delivered ``latency_ms`` late, and the faults of
:class:`~axis_ptz_ros2.sim.faults.FaultConfig` that act on the stream: stall, drop mid-part, truncated JPEGs, wrong
``Content-Length``, garbage between parts. Parts are written by :func:`axis_ptz_ros2.vapix.mjpeg.part_header`, the
package's one part writer.
"""

from __future__ import annotations

import collections
import contextlib
import os
import secrets
import socket
import time
from io import BufferedIOBase
from typing import Protocol

from axis_ptz_ros2.sim.faults import FaultConfig
from axis_ptz_ros2.sim.frames import stamp
from axis_ptz_ros2.sim.http.vapix import ImageRequest, Reply, image_args
from axis_ptz_ros2.sim.view import CameraView
from axis_ptz_ros2.vapix.mjpeg import multipart_content_type, part_header

BOUNDARY = "myboundary"


class VideoConnection(Protocol):
    """The HTTP connection a stream is written to (the server's request handler implements it)."""

    close_connection: bool
    protocol_version: str

    @property
    def cam(self) -> CameraView:
        """The camera this connection talks to."""
        ...

    @property
    def wfile(self) -> BufferedIOBase:
        """The connection's output stream."""
        ...

    @property
    def connection(self) -> socket.socket:
        """The connection's socket."""
        ...

    def log_request(self, code: int | str = "-", size: int | str = "-") -> None:
        """Log the status (the stdlib's hook)."""
        ...

    def send_response_only(self, code: int, message: str | None = None) -> None:
        """The status line alone."""
        ...

    def send_header(self, keyword: str, value: str) -> None:
        """One header line."""
        ...

    def end_headers(self) -> None:
        """The blank line after the headers."""
        ...

    def send(self, reply: Reply, extra: list[tuple[str, str]] | None = None) -> None:
        """A whole reply."""
        ...

    def write(self, data: bytes) -> None:
        """Write honouring the bandwidth cap fault."""
        ...

    def hold_silently(self) -> None:
        """Go mute while the camera drops packets, then reset the connection."""
        ...


class _StreamClosedError(Exception):
    """The MJPEG connection ended (client gone, camera stopped, or a drop fault)."""


def serve_video(handler: VideoConnection, args: list[tuple[str, str]]) -> None:
    """Answer ``video.cgi`` on ``handler``'s connection: the stream until it ends, then close."""
    try:
        req = image_args(handler.cam, args, video=True)
    except ValueError as err:
        handler.send(Reply(400, f"Error:\n{err}\n"))
        return
    # As a real Axis answers video.cgi: HTTP/1.0, no Server and no Date, caching forbidden three ways.
    handler.close_connection = True
    handler.protocol_version = "HTTP/1.0"  # this connection only: it closes after the stream
    handler.log_request(200)
    handler.send_response_only(200)
    handler.send_header("Cache-Control", "no-cache")
    handler.send_header("Pragma", "no-cache")
    handler.send_header("Expires", "Thu, 01 Dec 1994 16:00:00 GMT")
    handler.send_header("Connection", "close")
    handler.send_header("Content-Type", multipart_content_type(BOUNDARY))
    handler.end_headers()
    handler.cam.requests.count("", 200)
    with contextlib.suppress(_StreamClosedError, OSError):
        _stream(handler, req)
    if handler.cam.blackholed:
        handler.hold_silently()  # the camera went mute mid-stream: no FIN, the client must time out


def _stream(handler: VideoConnection, req: ImageRequest) -> None:
    cam = handler.cam
    w, h, comp, overlay = req.width, req.height, req.compression, req.overlay
    duration, nframes = req.duration, req.nbrofframes
    # the camera makes at most persona.frame_rate pictures a second (the PAL 214: 25): more asked, that many sent
    rate = cam.persona.frame_rate
    fps = min(req.fps, rate)
    period = 1.0 / fps if fps > 0 else 0.0
    start = time.monotonic()
    next_t = start
    pending: collections.deque[tuple[float, bytes]] = collections.deque()
    seq = 0
    stalled = False
    last_jpeg: bytes | None = None
    last_render = -1.0
    stop = cam.stopping
    gen = cam.generation
    # a stream whose handler got here just after a reboot began reads the new generation: the blackhole flag
    # mutes it all the same (seen: a stream that kept sending through a packet-dropping reboot)
    while not stop.is_set() and gen == cam.generation and not cam.blackholed:
        now = time.monotonic()
        if duration and now - start >= duration:
            return
        if nframes and seq >= nframes and not pending:
            return
        faults = cam.faults
        latency = faults.latency_ms / 1000.0
        produce = (not nframes or seq + len(pending) < nframes) and (
            (fps > 0 and now >= next_t) or (fps == 0 and not pending)
        )
        if produce:
            if fps == 0 and last_jpeg is not None and now - last_render < 1.0 / rate:
                jpeg = last_jpeg  # as fast as possible: resend the latest picture (new ones at the camera's rate)
            else:
                text = time.strftime(overlay) if req.clock else overlay
                jpeg = cam.frame_jpeg(w, h, comp, text)
                last_jpeg, last_render = jpeg, now
            pending.append((now + latency, jpeg))
            if fps > 0:
                next_t += period
                if next_t < now - period:  # fell behind (stall, slow client): do not burst
                    next_t = now + period
        while pending and pending[0][0] <= time.monotonic():
            _, jpeg = pending.popleft()
            seq += 1
            _send_part(handler, seq, jpeg, faults)
            cam.count_frame_sent()
            if faults.stall_after_frames and seq == faults.stall_after_frames and not stalled:
                stalled = True
                if stop.wait(faults.stall_seconds):
                    return
                next_t = time.monotonic()
            if faults.drop_after_frames and seq >= faults.drop_after_frames:
                # Drop mid-part: headers and half of the next JPEG, then close.
                nxt = cam.frame_jpeg(w, h, comp, overlay)
                handler.write(part_header(BOUNDARY, len(nxt)) + nxt[: len(nxt) // 2])
                handler.wfile.flush()
                with contextlib.suppress(OSError):
                    handler.connection.shutdown(socket.SHUT_RDWR)
                raise _StreamClosedError
        now = time.monotonic()
        wake = [0.05]
        if fps > 0:
            wake.append(next_t - now)
        if pending:
            wake.append(pending[0][0] - now)
        delay = min(wake)
        if fps == 0 and not pending:
            continue  # as fast as possible
        if delay > 0:
            stop.wait(delay)


def _send_part(handler: VideoConnection, seq: int, jpeg: bytes, faults: FaultConfig) -> None:
    data = stamp(jpeg, seq)
    if faults.truncate_every and seq % faults.truncate_every == 0:
        data = data[: max(16, len(data) // 2)]
    length = len(data)
    if faults.wrong_length_every and seq % faults.wrong_length_every == 0:
        length = max(0, length + faults.wrong_length_delta)
    part = part_header(BOUNDARY, length) + data + b"\r\n"
    if faults.garbage_between_parts:
        part += _garbage()
    handler.write(part)


def _garbage() -> bytes:
    n = 8 + secrets.randbelow(56)
    raw = os.urandom(n).replace(b"-", b"x")
    return raw + b"\r\n"
