"""Synchronous, typed VAPIX client for Axis PTZ cameras (ROS-free).

Implements reference ``vapix.md``: §2 (base URL, v2/v3 param.cgi paths, line endings), §3
(authentication via :class:`~axis_ptz_ros2.vapix.auth.NegotiatingAuth`), §4 (``ptz.cgi`` commands
and queries, ``ptzconfig.cgi`` presets, ``Error:`` bodies), §5 (``mjpg/video.cgi`` stream,
``jpg/image.cgi`` snapshot, ``imagesize.cgi`` for CIF names), §6 (``param.cgi?action=list``) and
the robustness checklist of §12.

:class:`VapixClient` is built in layers, one job per module: :mod:`.transport` (the kept-alive connection,
authentication, capped replies, typed errors, the poll's quick path), :mod:`.device` (``param.cgi``, resolutions,
device info), this module (PTZ commands and queries, snapshots, opening MJPEG streams); :mod:`.mjpeg_stream` is a
running stream, :mod:`.camera_config` where and how to reach the camera, :mod:`.replies` paths and reply text.

Threading: one PTZ caller (serialised by a lock) plus any number of
:class:`~axis_ptz_ros2.vapix.mjpeg_stream.MjpegStream` objects, each on its own ``httpx.Client`` (all sharing one
SSL context), so a long-lived video stream never blocks PTZ polling.
Credentials live only in :class:`~axis_ptz_ros2.vapix.camera_config.CameraConfig` (``repr=False``) and the auth
objects; URLs and error messages never contain them.
"""

from __future__ import annotations

import ssl
import threading

import httpx

from axis_ptz_ros2.vapix.auth import AuthCounters, NegotiatingAuth
from axis_ptz_ros2.vapix.camera_config import CameraConfig
from axis_ptz_ros2.vapix.device import VapixDevice
from axis_ptz_ros2.vapix.errors import (
    AxisPtzError,
    CommandRejected,
    InvalidArgument,
    ResponseParseError,
)
from axis_ptz_ros2.vapix.mjpeg_stream import VIDEO_CGI, MjpegStream
from axis_ptz_ros2.vapix.models import (
    Preset,
    PtzLimits,
    PtzPosition,
    VideoParams,
    parse_int,
    parse_key_values,
)
from axis_ptz_ros2.vapix.replies import build_path, decode_text, parse_error_body
from axis_ptz_ros2.vapix.requests import PTZ_CGI, PtzQuery, PtzRequest

__all__ = ["VapixClient"]

MAX_SNAPSHOT_BYTES = 32 << 20  #: cap on one snapshot JPEG
IMAGE_CGI = "/axis-cgi/jpg/image.cgi"


class VapixClient(VapixDevice):
    """Typed access to one Axis camera over one kept-alive ``httpx.Client``."""

    def __init__(
        self,
        config: CameraConfig,
        *,
        transport: httpx.BaseTransport | None = None,
        auth_counters: AuthCounters | None = None,
    ) -> None:
        """``transport`` is injected by tests (``httpx.MockTransport``); default: a real HTTP transport.
        ``auth_counters`` may be shared by several clients of one camera (diagnostics add them up once)."""
        super().__init__(config, transport=transport, auth_counters=auth_counters)
        self._stream_ssl: ssl.SSLContext | None = None  # every MJPEG stream's, built once (_stream_ssl_context)
        self._stream_ssl_lock = threading.Lock()
        self._limits: PtzLimits | None = None

    @property
    def limits(self) -> PtzLimits | None:
        """Limits from the last :meth:`query_limits` (used to validate every command)."""
        return self._limits

    def __repr__(self) -> str:
        """No credentials."""
        return f"VapixClient({self._config!r})"

    # -- PTZ ------------------------------------------------------------------------------------

    def ptz(self, cmd: PtzRequest) -> None:
        """Validate ``cmd`` (against :attr:`limits` when known) and send it; expects 204/2xx.

        Raises :class:`InvalidArgument` before sending, :class:`CommandRejected` on an ``Error:``
        body, or the mapped transport/status error.
        """
        cmd.validate(self._limits)
        self._get_text(build_path(cmd.path, {**self._camera_args(), **cmd.query()}))

    def _query(self, what: PtzQuery) -> str:
        path_query = build_path(PTZ_CGI, {**self._camera_args(), "query": what.value})
        if self._quick is not None:
            text = self._quick_text(path_query)
            if text is not None:
                return text
        _, text = self._get_text(path_query)
        return text

    def query_position(self) -> PtzPosition:
        """``query=position`` (§4.4)."""
        return PtzPosition.parse(self._query(PtzQuery.POSITION))

    def query_limits(self) -> PtzLimits:
        """``query=limits``, falling back to ``param.cgi`` ``PTZ.Limit.L<camera>``; cached for validation."""
        try:
            limits = PtzLimits.parse(self._query(PtzQuery.LIMITS))
        except (CommandRejected, ResponseParseError) as query_err:
            try:
                limits = PtzLimits.from_params(self.list_params("PTZ.Limit"), camera=self._config.camera)
            except AxisPtzError:
                raise query_err from None
        self._limits = limits
        return limits

    def query_presets(self) -> tuple[Preset, ...]:
        """``query=presetposcam`` → presets sorted by number."""
        return Preset.parse_list(self._query(PtzQuery.PRESETPOSCAM))

    def query_speed(self) -> int:
        """``query=speed`` → 1..100."""
        values = parse_key_values(self._query(PtzQuery.SPEED))
        if "speed" not in values:
            raise ResponseParseError(f"query=speed: no 'speed' in reply (keys: {sorted(values)})")
        return parse_int(values["speed"], key="speed")

    def query_attributes(self) -> dict[str, str]:
        """``query=attributes`` (newer firmware only, §4.4): ``maxOpticalZoomMag``, ``maxDigitalZoomMag``,
        ``zoomSteps``, ``speeds`` as raw text values. Raises :class:`CommandRejected` where unsupported."""
        return parse_key_values(self._query(PtzQuery.ATTRIBUTES))

    # -- video ----------------------------------------------------------------------------------

    def video_path(self, params: VideoParams) -> str:
        """Path and query of the MJPEG request, e.g. for logging (no host, no credentials)."""
        return build_path(VIDEO_CGI, params.query())

    def snapshot(self, params: VideoParams) -> bytes:
        """One JPEG from ``jpg/image.cgi`` (``fps`` is not sent)."""
        params.validate(self._resolutions)
        # a large JPEG over a slow link may take a while: the time cap only has to end an endless reply
        response, body = self._get(
            build_path(IMAGE_CGI, params.query(include_fps=False)),
            MAX_SNAPSHOT_BYTES,
            total_s=max(30.0, 4.0 * self._config.timeout_s),
        )
        if not body.startswith(b"\xff\xd8"):
            message = parse_error_body(decode_text(body))
            if message is not None:
                raise CommandRejected(f"{IMAGE_CGI}: camera says {message!r}", camera_message=message)
            ctype = response.headers.get("content-type", "?")
            raise ResponseParseError(f"{IMAGE_CGI}: expected a JPEG, got {ctype} ({len(body)} bytes)")
        return body

    def open_mjpeg(self, params: VideoParams, read_timeout_s: float = 5.0) -> MjpegStream:
        """Open ``mjpg/video.cgi`` on a separate connection; iterate the result for JPEG frames."""
        params.validate(self._resolutions)
        if read_timeout_s <= 0:
            raise InvalidArgument(f"read timeout must be positive, got {read_timeout_s}")
        auth = NegotiatingAuth(
            self._config.username,
            self._config.password,
            self._config.auth,
            initial_scheme=self._auth.scheme,
            counters=self.auth_counters,
        )
        http = self._new_http(
            auth, self._config.timeout(read_timeout_s), self._transport, verify=self._stream_ssl_context()
        )
        stream = MjpegStream(http, self.video_path(params), auth, self._secrets())
        try:
            stream._open()
        except BaseException:
            stream.close()
            raise
        return stream

    def _stream_ssl_context(self) -> ssl.SSLContext:
        """The SSL context of every MJPEG stream of this client, built once (thread-safe).

        Given ``verify=True`` (or ``False``), httpx builds a new context for each client, and for ``True`` parses
        the CA bundle into OpenSSL each time: with a context per reconnect the reader thread's malloc arena grew
        ~0.2-0.35 MB per reconnect without bound, although every context was freed (issue 25).
        One context serves any number of connections; it is also what a plain-HTTP camera's client is handed
        (httpx wants one; with redirects off it is never used)."""
        with self._stream_ssl_lock:
            if self._stream_ssl is None:
                self._stream_ssl = httpx.create_ssl_context(verify=self._verify, trust_env=False)
            return self._stream_ssl
