"""A running MJPEG request (``mjpg/video.cgi``, reference ``vapix.md`` §5): iterate it for JPEG frames, close it from
any thread (ROS-free). Opened by :meth:`axis_ptz_ros2.vapix.client.VapixClient.open_mjpeg`, each stream on its own
``httpx.Client``, so a long-lived video stream never blocks PTZ polling."""

from __future__ import annotations

import contextlib
import socket
import threading
from collections.abc import Iterator

import httpx

from axis_ptz_ros2.vapix.auth import NegotiatingAuth
from axis_ptz_ros2.vapix.errors import (
    CommandRejected,
    ResponseParseError,
    check_status,
    map_httpx_error,
    redact,
)
from axis_ptz_ros2.vapix.mjpeg import MjpegParser, MjpegStats, boundary_from_content_type
from axis_ptz_ros2.vapix.replies import decode_text, parse_error_body
from axis_ptz_ros2.vapix.transport import ClosesOnExit

__all__ = ["VIDEO_CGI", "MjpegStream"]

VIDEO_CGI = "/axis-cgi/mjpg/video.cgi"


class MjpegStream(ClosesOnExit):
    """A running MJPEG request: iterate for frames; :meth:`close` may be called from any thread."""

    def __init__(
        self, http: httpx.Client, path_query: str, auth: NegotiatingAuth, secrets: tuple[str | None, ...]
    ) -> None:
        """Use :meth:`VapixClient.open_mjpeg`."""
        self._http = http
        self._path = path_query
        self._auth = auth
        self._secrets = secrets
        self._response: httpx.Response | None = None
        self._parser: MjpegParser | None = None
        self._closed = threading.Event()
        self._lock = threading.Lock()
        self._reading = False
        self._released = False

    @property
    def path(self) -> str:
        """Path and query of the request."""
        return self._path

    @property
    def content_type(self) -> str:
        """The ``Content-Type`` the camera announced."""
        return self._response.headers.get("content-type", "") if self._response is not None else ""

    @property
    def stats(self) -> MjpegStats:
        """Parser counters so far."""
        return self._parser.stats if self._parser is not None else MjpegStats()

    @property
    def closed(self) -> bool:
        """Whether :meth:`close` was called."""
        return self._closed.is_set()

    def _open(self) -> None:
        request = self._http.build_request("GET", self._path)
        try:
            response = self._http.send(request, stream=True)
        except httpx.HTTPError as err:
            raise map_httpx_error(err, self._secrets) from err
        self._response = response
        if not 200 <= response.status_code < 300:
            with contextlib.suppress(httpx.HTTPError):
                response.read()
            hint = self._auth.failure_hint(response) if response.status_code in (401, 403) else ""
            check_status(response, auth_hint=redact(hint, self._secrets))
        ctype = response.headers.get("content-type", "")
        if not ctype.lower().startswith("multipart/"):
            text = ""
            with contextlib.suppress(httpx.HTTPError):
                text = decode_text(response.read()[:4096])
            message = parse_error_body(text)
            if message is not None:
                raise CommandRejected(f"{VIDEO_CGI}: camera says {message!r}", camera_message=message)
            raise ResponseParseError(f"{VIDEO_CGI}: expected multipart/x-mixed-replace, got {ctype!r}")
        self._parser = MjpegParser(boundary_from_content_type(ctype))

    def __iter__(self) -> Iterator[bytes]:
        """Yield each complete JPEG as it arrives; ends quietly after :meth:`close` or end of stream.

        Iterate once: when the iteration ends (end of stream, ``break``, error) the stream is closed.
        """
        response, parser = self._response, self._parser
        if response is None or parser is None:
            return
        raw = response.iter_raw()
        try:
            while not self._closed.is_set():
                with self._lock:
                    if self._closed.is_set():
                        break
                    self._reading = True
                try:
                    chunk = next(raw, None)
                except httpx.HTTPError as err:
                    if self._closed.is_set():
                        break
                    raise map_httpx_error(err, self._secrets) from err
                except (OSError, ValueError):
                    if self._closed.is_set():  # socket shut down under us by close()
                        break
                    raise
                finally:
                    with self._lock:
                        self._reading = False
                if self._closed.is_set():  # closed while we were blocked: drop what arrived late
                    break
                frames = parser.close() if chunk is None else parser.feed(chunk)
                for frame in frames:
                    if self._closed.is_set():
                        break
                    yield frame
                if chunk is None:
                    break
        finally:
            self._closed.set()
            self._release()

    def close(self) -> None:
        """Stop the stream; safe from another thread (wakes a reader blocked on a stalled camera)."""
        with self._lock:
            self._closed.set()
            reading = self._reading
        if reading:
            self._shutdown_socket()  # the reader wakes up, sees the flag and releases
        else:
            self._release()

    def _shutdown_socket(self) -> None:
        response = self._response
        if response is None:
            return
        stream = response.extensions.get("network_stream")
        get_extra = getattr(stream, "get_extra_info", None)
        sock = get_extra("socket") if get_extra is not None else None
        if isinstance(sock, socket.socket):
            with contextlib.suppress(OSError):
                sock.shutdown(socket.SHUT_RDWR)

    def _release(self) -> None:
        with self._lock:
            if self._released:
                return
            self._released = True
        if self._response is not None:
            with contextlib.suppress(httpx.HTTPError, OSError):
                self._response.close()
        self._http.close()
