"""Pass-through of a camera's own RTSP H.264 for the stream node: one reader thread, no re-encoding. ROS-free.

:class:`RtspH264Source` plays the camera's ``/axis-media/media.amp`` with
:class:`~axis_ptz_ros2.vapix.rtsp_client.RtspClient` (our client: it owns the playing session, so
``SET_PARAMETER`` ``Renew-Stream: yes`` reaches the stream we play) and hands every access unit, stamped on this
host's clock (its RTP time mapped by :class:`~axis_ptz_ros2.streaming.clock_sync.StreamClock`: the capture time
plus the network's least delay, or the camera's least latency before a sender report; never backwards, whatever
the camera's clock says; the camera's clock offset is in
:attr:`RtspSourceStats.camera_clock_offset_s`, and a camera more than 1 s off is reported once), to a sink: the
stream node's
:class:`~axis_ptz_ros2.streaming.h264.H264Stage` (:meth:`~axis_ptz_ros2.streaming.h264.H264Stage.on_access_unit`),
which puts SPS/PPS in front of every IDR and publishes on both H.264 topics.

* Lazy: nothing runs (no TCP connection) while :meth:`RtspH264Source.set_active` is off.
* Before the first connection the camera is asked once whether it streams H.264 (``Properties.Image.Format``);
  one that does not (the 214) is reported through ``on_supported(False)`` and never asked for RTSP: the node
  transcodes its MJPEG instead.
* The request (:class:`~axis_ptz_ros2.vapix.rtsp.MediaStreamRequest`: size, fps, fixed GOP of at most one second,
  baseline, ``mbr`` at the bitrate in force, ``adjustablelivestream=1`` until the camera refuses it) is read from
  ``request()`` on every access unit: the stream node's is the request its pipeline last decided (it is pushed
  there, :mod:`.pipeline`; reading it asks nothing of the controller). A bitrate change is applied to the playing
  stream with ``Adjustable-Stream-Configuration``; where the camera cannot (no ``adjustablelivestream``), it
  reconnects when the bitrate moves by more than :data:`BITRATE_SLACK`, at most every :data:`BITRATE_HOLD_S` (a
  link budget that moves a little must not cut the stream over and over). Any other change reconnects.
* An IDR wanted by the sink (a new subscriber, a consumer's loss report) → ``Renew-Stream``, then ``idr_sent()``.
* Errors reconnect with :class:`~axis_ptz_ros2.streaming.meter.Backoff` counted from the start of the failed
  attempt; a read timeout (a stalled or rebooting camera) ends the session; a new session starts with an IDR (it
  counts as the one the sink wanted), and access units queued on a dead connection are dropped with it, never published.
  Messages never carry the URL's credentials (the client never puts them there).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Final, Protocol

from axis_ptz_ros2.media import annexb
from axis_ptz_ros2.media.errors import BitstreamError
from axis_ptz_ros2.media.frame import EncodedFrame
from axis_ptz_ros2.media.h264_settings import H264Settings
from axis_ptz_ros2.streaming.clock_sync import StreamClock
from axis_ptz_ros2.streaming.meter import Backoff
from axis_ptz_ros2.streaming.reader import ReaderConfig
from axis_ptz_ros2.streaming.wall_clock import WallClockSteps
from axis_ptz_ros2.streaming.worker import Worker
from axis_ptz_ros2.vapix.camera_config import CameraConfig
from axis_ptz_ros2.vapix.client import VapixClient
from axis_ptz_ros2.vapix.errors import AuthError, AxisPtzError, CommandRejected
from axis_ptz_ros2.vapix.models import VideoParams
from axis_ptz_ros2.vapix.rtsp import MediaStreamRequest, RtspStatusError
from axis_ptz_ros2.vapix.rtsp_client import RtspClient
from axis_ptz_ros2.vapix.rtsp_rtp import RtpAccessUnit
from axis_ptz_ros2.vapix.rtsp_sdp import RtspUnsupportedError

#: a bitrate change smaller than this fraction of the one playing does not reconnect
BITRATE_SLACK: Final = 0.2
#: s: bitrate-only reconnections at most this often
BITRATE_HOLD_S: Final = 3.0


class AccessUnitSink(Protocol):
    """Where access units go (:class:`~axis_ptz_ros2.streaming.h264.H264Stage` is one)."""

    def on_access_unit(self, frame: EncodedFrame, stamp_ns: int) -> object:
        """Publish one access unit stamped ``stamp_ns``."""
        ...

    @property
    def idr_wanted(self) -> bool:
        """An IDR has been asked for and not yet given."""
        ...

    def idr_sent(self) -> None:
        """The camera has been asked for an IDR."""
        ...


class RtspSession(Protocol):
    """A playing RTSP session (:class:`~axis_ptz_ros2.vapix.rtsp_client.RtspClient` is one)."""

    def open(self) -> None:
        """Connect and play."""
        ...

    def close(self) -> None:
        """Tear down; from any thread."""
        ...

    def read(self, timeout_s: float | None = None) -> RtpAccessUnit:
        """The next access unit (raises :class:`AxisPtzError` kinds)."""
        ...

    def renew_stream(self) -> object:
        """``Renew-Stream: yes``."""
        ...

    def adjust_stream(self, *, fps: int | None = None, max_bitrate_kbps: int | None = None) -> object:
        """``Adjustable-Stream-Configuration`` (raises :class:`RtspStatusError` when the camera refuses it)."""
        ...


@dataclass(slots=True)
class RtspSourceStats:
    """Counters since the source was made (diagnostics)."""

    access_units: int = 0
    connects: int = 0
    reconnects: int = 0
    renews: int = 0
    adjustments: int = 0  #: bitrate changes applied to the playing stream (Adjustable-Stream-Configuration)
    refused: int = 0  #: access units the sink could not take (malformed)
    last_error: str = ""
    #: s: the camera's wall clock behind (+) or ahead (−) of the host's (RTCP sender reports); None before one
    camera_clock_offset_s: float | None = None


def camera_streams_h264(client: VapixClient) -> bool:
    """Whether the camera lists ``h264`` in ``Properties.Image.Format`` (a camera without the parameter: no)."""
    try:
        formats = client.list_params("Properties.Image.Format").get("Properties.Image.Format", "")
    except CommandRejected:
        return False
    return "h264" in {f.strip().lower() for f in formats.split(",")}


def media_request(params: VideoParams, h264: H264Settings) -> MediaStreamRequest:
    """What to ask the camera's RTSP server for: the size and fps in effect, a fixed GOP of the stage's periodic
    IDR interval (at most one second), the bitrate in force as ``videomaxbitrate`` (in the encoder's range, which
    is what a camera's ``videomaxbitrate`` takes: :class:`H264Settings` holds it to it)."""
    res = params.resolution
    return MediaStreamRequest(
        resolution=f"{res.width}x{res.height}",
        fps=max(1, int(params.fps)),
        keyframe_interval=h264.gop_frames,
        max_bitrate_kbps=h264.bitrate_kbps,
    )


def rtsp_connector(config: CameraConfig, rtsp_port: int) -> Callable[[MediaStreamRequest, float], RtspClient]:
    """``connect(request, read_timeout_s)`` for :class:`RtspH264Source`: our client on the camera's RTSP port, with
    its credentials and authentication mode (the URL it builds carries none)."""

    def connect(request: MediaStreamRequest, read_timeout_s: float) -> RtspClient:
        return RtspClient(
            config.host,
            rtsp_port,
            stream=request,
            username=config.username,
            password=config.password,
            auth=config.auth,
            open_timeout_s=max(config.connect_timeout_s, read_timeout_s),
            read_timeout_s=read_timeout_s,
        )

    return connect


def request_size(request: MediaStreamRequest) -> tuple[int, int]:
    """``(width, height)`` of a request."""
    w, _, h = request.resolution.partition("x")
    return int(w), int(h)


def same_but_rate(a: MediaStreamRequest, b: MediaStreamRequest) -> bool:
    """Whether two requests differ at most in their bitrate."""
    return replace(a, max_bitrate_kbps=b.max_bitrate_kbps) == b


def needs_reconnect(playing: MediaStreamRequest, wanted: MediaStreamRequest, since_s: float) -> bool:
    """Whether ``wanted`` differs enough from the request ``playing`` (for ``since_s``) to reconnect."""
    if playing == wanted:
        return False
    if not same_but_rate(playing, wanted):
        return True
    moved = abs(wanted.max_bitrate_kbps - playing.max_bitrate_kbps) / max(1, playing.max_bitrate_kbps)
    return moved > BITRATE_SLACK and since_s >= BITRATE_HOLD_S


class RtspH264Source:
    """The pass-through reader thread (see the module docstring); control methods are thread-safe."""

    def __init__(
        self,
        connect: Callable[[MediaStreamRequest, float], RtspSession],
        request: Callable[[], MediaStreamRequest],
        sink: AccessUnitSink,
        *,
        supports_h264: Callable[[], bool],
        on_supported: Callable[[bool], None],
        on_event: Callable[[str], None] | None = None,
        config: ReaderConfig | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        """``connect(request, read_timeout_s)``: an unopened session for ``request``; ``supports_h264()``: ask the
        camera (raises :class:`AxisPtzError` when it cannot say); ``on_event(text)``: errors and reconnects;
        ``config``: the MJPEG reader's timing (:class:`~axis_ptz_ros2.streaming.reader.ReaderConfig`; its meter
        window is not used here)."""
        self._connect = connect
        self._request = request
        self._sink = sink
        self._supports = supports_h264
        self._on_supported = on_supported
        self._on_event = on_event
        self._config = config or ReaderConfig()
        self._clock = clock
        cfg = self._config
        self._backoff = Backoff(cfg.backoff_initial_s, max(cfg.backoff_max_s, cfg.backoff_initial_s))
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._worker = Worker("RTSP source", "axis-rtsp-h264", self._run, self._interrupt, active=False)
        self._stop = self._worker.stopping
        self._session: RtspSession | None = None
        self._last_au: float | None = None
        self._adjustable = True  #: ask for adjustablelivestream=1 until the camera refuses it
        self.supported: bool | None = None  #: None until the camera has said whether it streams H.264
        self.stats = RtspSourceStats()
        self.stamps = StreamClock()  #: RTP time → host time, never backwards (one per stream, across sessions)
        self.host_clock = WallClockSteps()  #: this host's clock steps, which the stamps follow

    # -- control (any thread) ----------------------------------------------------------------------------------
    @property
    def active(self) -> bool:
        """Whether the source is to play."""
        return self._worker.active

    def start(self) -> None:
        """Start the thread (once); it idles until :meth:`set_active`."""
        self._worker.start()

    def stop(self, timeout: float = 1.5) -> bool:
        """Stop and join; False if the thread did not end within ``timeout``."""
        return self._worker.stop(timeout)

    def set_active(self, active: bool) -> None:
        """Play (asking the camera first whether it can) or stop playing."""
        self._worker.set_active(active)

    # -- the thread ----------------------------------------------------------------------------------------------
    def _interrupt(self) -> None:
        self._wake.set()
        with self._lock:
            session = self._session
        if session is not None:
            session.close()  # a blocked read ends at once

    def _event(self, text: str) -> None:
        self.stats.last_error = text
        if self._on_event is not None:
            self._on_event(text)

    def _run(self) -> None:
        while not self._stop.is_set():
            self._wake.clear()
            if not self.active or self.supported is False:
                self._backoff.reset()
                self._wake.wait()
                continue
            attempt = self._clock()
            if self.supported is None:
                try:
                    supported = bool(self._supports())
                except AxisPtzError as err:
                    self._event(f"cannot ask the camera whether it streams H.264: {err}")
                    self._wake.wait(self._backoff.next_after(self._clock() - attempt))
                    continue
                self.supported = supported
                self._on_supported(supported)
                continue
            try:
                request = replace(self._request(), adjustable=self._adjustable)
                session = self._connect(request, self._config.read_timeout(request.fps))
                session.open()
            except AuthError as err:
                self.stats.reconnects += 1
                self._event(str(err))
                if self._last_au is not None and self._clock() - self._last_au < self._config.auth_grace_s:
                    # frames flowed with these credentials moments ago: a camera still booting (as the MJPEG reader)
                    self._wake.wait(self._backoff.next_after(self._clock() - attempt))
                else:
                    self._wake.wait(self._config.auth_retry_s)
                continue
            except RtspStatusError as err:
                if request.adjustable and err.status_code in (400, 415, 451):
                    self._adjustable = False  # firmware without adjustablelivestream: bitrate changes reconnect
                    self._event(f"RTSP H.264: {err} with adjustablelivestream=1; asking without it")
                    continue
                self.stats.reconnects += 1
                self._event(f"RTSP H.264: cannot play: {_reason(err)}")
                self._wake.wait(self._backoff.next_after(self._clock() - attempt))
                continue
            except RtspUnsupportedError as err:  # no H.264 in its SDP, or UDP only: asking again will not help
                self.supported = False
                self._event(f"RTSP H.264: {err}; transcoding the camera's MJPEG instead")
                self._on_supported(False)
                continue
            except (AxisPtzError, OSError) as err:  # (a refused or unanswered connect is a bare OSError)
                self.stats.reconnects += 1
                self._event(f"RTSP H.264: cannot play: {_reason(err)}")
                self._wake.wait(self._backoff.next_after(self._clock() - attempt))
                continue
            self._play(session, request)

    def _play(self, session: RtspSession, request: MediaStreamRequest) -> None:
        with self._lock:
            if self._stop.is_set() or not self.active:
                session.close()
                return
            self._session = session
        self.stats.connects += 1
        self.stamps.new_session()
        self._sink.idr_sent()  # a new session starts with an IDR (PLAY): what was wanted is on its way
        width, height = request_size(request)
        opened = self._clock()
        read_timeout = self._config.read_timeout(request.fps)
        error = ""
        try:
            while not self._stop.is_set() and self.active:
                wanted = replace(self._request(), adjustable=request.adjustable)
                if wanted != request and request.adjustable and same_but_rate(request, wanted):
                    try:
                        session.adjust_stream(max_bitrate_kbps=wanted.max_bitrate_kbps)
                    except RtspStatusError as err:
                        self._adjustable = False
                        self._event(f"RTSP H.264: bitrate not adjustable live ({err}): reconnecting for it")
                        break
                    request = wanted
                    self.stats.adjustments += 1
                elif needs_reconnect(request, wanted, self._clock() - opened):
                    break
                if self._sink.idr_wanted:
                    session.renew_stream()
                    self._sink.idr_sent()
                    self.stats.renews += 1
                au = session.read(read_timeout)
                self._last_au = self._clock()
                if au.keyframe:
                    width, height = _size_of(au.data, (width, height))
                    self._backoff.reset()
                stamp = self._stamp(au)
                frame = EncodedFrame(au.data, au.keyframe, self.stats.access_units, width, height, au.capture_ns)
                self.stats.access_units += 1
                if self._sink.on_access_unit(frame, stamp) is None:
                    self.stats.refused += 1
        except Exception as err:  # noqa: BLE001 - the thread must survive anything (a publish during shutdown …)
            error = _reason(err)
        finally:
            with self._lock:
                self._session = None
            session.close()
        if error and not self._stop.is_set() and self.active:
            self.stats.reconnects += 1
            self._event(f"RTSP H.264 stream lost: {error}")
            self._wake.wait(self._backoff.next())

    def _stamp(self, au: RtpAccessUnit) -> int:
        """Host time of ``au`` (its RTP time through :class:`StreamClock`), the camera's offset in the stats."""
        read = au.arrival_ns if au.arrival_ns is not None else time.time_ns()
        step, arrival = self.host_clock.check_read(read)  # (read in the receive thread, perhaps before a step)
        report_arrival = au.report_arrival_ns
        if step:
            # the host's clock stepped (NTP, chrony): the stamps move with it, as every other stamp on this host
            self.stamps.host_clock_stepped(step)
            if self._on_event is not None:
                self._on_event(f"this host's clock stepped by {step / 1e9:+.3f} s: the H.264 stamps follow it")
            if report_arrival is not None:
                report_arrival += arrival - read  # read with the access unit: on the same clock
        if au.report_rtp is not None and report_arrival is not None:
            self.stamps.sender_report(au.report_rtp, report_arrival)
        stamp = self.stamps.stamp(au.rtp_timestamp, arrival, au.capture_ns)
        offset = self.stamps.camera_offset_ns
        self.stats.camera_clock_offset_s = None if offset is None else offset / 1e9
        if offset is not None and self.stamps.take_offset_warning() and self._on_event is not None:
            side = "behind" if offset > 0 else "ahead of"
            self._on_event(
                f"RTSP H.264: the camera's clock is {abs(offset) / 1e9:.1f} s {side} this host's: set NTP on the "
                "camera (frames are stamped on this host's clock)"
            )
        return stamp


def _reason(err: BaseException) -> str:
    """An error for a log line: our typed errors say what happened (never with credentials); others by kind."""
    if isinstance(err, AxisPtzError):
        return str(err)
    if isinstance(err, OSError):
        return f"{type(err).__name__} ({err.strerror or 'timed out'})"
    return type(err).__name__


def _size_of(access_unit: bytes, fallback: tuple[int, int]) -> tuple[int, int]:
    """The picture size from the SPS in an IDR access unit (the camera's, which may differ from the request)."""
    try:
        sps = annexb.find_sps(access_unit)
    except BitstreamError:
        return fallback
    return (sps.width, sps.height) if sps is not None else fallback


def passthrough_source(
    client: VapixClient,
    rtsp_port: int,
    request: Callable[[], MediaStreamRequest],
    sink: AccessUnitSink,
    timing: ReaderConfig,
    *,
    on_supported: Callable[[bool], None],
    on_event: Callable[[str], None],
) -> RtspH264Source:
    """The stream node's pass-through source: the camera of ``client`` (its host, credentials, auth mode) on
    ``rtsp_port``, asked for ``request()`` (the request last decided and pushed by the pipeline, :mod:`.pipeline`:
    no decision is made per access unit), with the MJPEG reader's timing."""
    return RtspH264Source(
        rtsp_connector(client.config, rtsp_port),
        request,
        sink,
        supports_h264=lambda: camera_streams_h264(client),
        on_supported=on_supported,
        on_event=on_event,
        config=timing,
    )
