"""The H.264 stage of the stream node (the robot's side): one encoded stream for every H.264 subscriber. ROS-free.

The subscribers' side (pts gaps, decoding, what could not be shown) is :mod:`.receiver`.

Where the access units come from is a seam: :meth:`H264Stage.on_jpeg` feeds the JPEGs the reader delivers
through one shared :class:`~axis_ptz_ros2.media.transcoder.MjpegTranscoder` (cameras that only stream MJPEG, the
214); :meth:`H264Stage.on_access_unit` takes access units from any other source (an RTSP pass-through reader,
:mod:`axis_ptz_ros2.vapix.rtsp`) and gives them the same treatment. Either way, what is handed to ``publish``:

* one Annex B access unit per call, SPS/PPS in front of every IDR (prepended from the last ones seen when a
  source does not repeat them in-band, as real Axis cameras do not);
* ``pts``: a unique, strictly increasing counter of the stage (it survives encoder re-opens and source changes);
* the frame's capture time: the stamp of the JPEG or access unit it came from (a JPEG's is its arrival on this
  host, as ``image_raw/compressed`` is stamped; an RTSP access unit's is the one its source gives), the same in
  the message's header and, for a transcoded frame, in the access unit's capture-stamp SEI
  (:func:`~axis_ptz_ros2.media.annexb.insert_capture_stamp`). Nothing in a JPEG's bytes is read for it.

Policy that lives here:

* lazy: while :meth:`H264Stage.set_active` is off nothing is decoded or encoded, and the transcoder (its
  encoder) is dropped; the next activation starts with an IDR;
* bitrate, keyframe interval, preset and fps are read from ``settings()`` (the video controller) on every frame;
  the bitrate changes live, a new preset or fps re-opens the encoder (an IDR follows), and so does a ceiling
  (:attr:`H264Settings.max_bitrate_kbps`) above the rate it was opened with: once, at that ceiling, when the link
  lets the bitrate climb past ``h264_bitrate_kbps`` (not at every step of the climb); a new VBV buffer
  (:attr:`H264Settings.vbv_kbit`, which follows the link's budget) takes effect at the encoder's next IDR, costing
  none of its own;
* the keyframe interval is at most one second of frames (``fps``). The encoder's refresh
  (:attr:`H264Settings.refresh`, by default ``intra``) says what it is: with x264's periodic intra refresh (issue
  39) the period of the wave of intra blocks that sweeps the picture, so a decoder that lost an access unit without
  asking shows a clean picture again within two waves, and no IDR is made after the first but on demand (an
  IDR every second, squeezed into the small VBV buffer a weak link asks for, blurred the picture once a second:
  PSNR 5th percentile 5 dB under the median; ``bench/encoder_tradeoff.py``, docs/weak-link.md); with ``idr`` the
  period of IDRs, as before. The profile (:attr:`H264Settings.profile`) is High by default (CABAC, the 8x8
  transform; still no B-frames): every decoder a viewer uses here decodes it (docs/nodes.md);
* an IDR on demand (:meth:`H264Stage.request_idr`: a new subscriber, a consumer that reports loss, a reconnect;
  with intra refresh the only start points a viewer gets)
  at most every :data:`IDR_MIN_INTERVAL_S` (a lossy link that reports loss on every frame must not be sent
  nothing but IDRs); a request inside that interval is kept for when it ends;
* a new subscriber (:meth:`H264Stage.new_subscriber`) gets an IDR at once and another
  :data:`NEW_SUBSCRIBER_IDR_AGAIN_S` later: the publisher learns of the subscription before the subscriber has
  learnt of the publisher as often as not, and an IDR sent in between never reaches it (weak-link bench, 8 starts
  of a plain subscriber at 2e4b659: in 6 its first access unit, 0.1-0.4 s after its node was up, was a P-frame,
  and its first picture waited for the periodic IDR, 1.1-1.4 s);
* a consumer's report of access units it could not show (:meth:`H264Stage.consumer_errors`, a count over the
  report's window) asks for an IDR only when the count grew since that consumer's last report: a consumer that
  has recovered keeps reporting the old errors for the rest of its window, and answering each of those reports
  with an IDR (four per loss on 2 Mbit/s with 2 % loss) spent the bitrate on IDRs, whose many packets were then
  the likeliest to be lost;
* a JPEG that does not decode is counted and dropped (the encoder is left as it was: nothing stale is sent);
* the encoder runs at the rate the camera really makes, not the one asked for: x264 spends ``bitrate / fps`` on
  each picture, and a PAL camera asked for 30 makes 25 (thesis Table 6.5: 24.8/s), which left 17 % of the bitrate
  unused (723 of 1000 kbit/s on the weak-link bench). The rate is the median interval of the last
  :data:`RATE_WINDOW` JPEGs' arrivals (a stall or a reconnect is one long interval, not a new rate); the encoder
  re-opens at it (an IDR) when it is :data:`RATE_REOPEN_FPS` or more from the rate it runs at, never above the
  rate asked for.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Final, Protocol

from axis_ptz_ros2.media import annexb
from axis_ptz_ros2.media.errors import BitstreamError, MediaError
from axis_ptz_ros2.media.frame import EncodedFrame
from axis_ptz_ros2.media.h264_settings import H264Settings
from axis_ptz_ros2.media.pyav import PyAvUnavailableError
from axis_ptz_ros2.streaming.meter import ConsumerCounts

#: s: on-demand IDRs at most this often (the periodic ones come every second anyway)
IDR_MIN_INTERVAL_S: Final = 0.25
#: s: a new subscriber's second IDR comes this long after its first (see the module docstring)
NEW_SUBSCRIBER_IDR_AGAIN_S: Final = 0.4
#: JPEG arrivals whose median interval gives the camera's own picture rate
RATE_WINDOW: Final = 30
#: pictures/s: the encoder re-opens at the measured rate only when it is this far from the one it runs at
RATE_REOPEN_FPS: Final = 2
#: ``encoding`` of every FFMPEGPacket: codec; the pixel format it was encoded from; what a decoder hands
#: cv_bridge; the ROS image encoding (what ffmpeg_image_transport's decoder parses)
FFMPEG_ENCODING: Final = "h264;yuv420p;bgr8;bgr8"


@dataclass(slots=True)
class StageStats:
    """Counters since the stage was made (diagnostics)."""

    frames: int = 0  # access units published
    idrs: int = 0
    idr_requests: int = 0  # on-demand requests honoured
    bad_inputs: int = 0  # JPEGs that did not decode, malformed access units
    encoder_opens: int = 0  # transcoders (encoders) made
    fps_reopens: int = 0  # of those, re-made for a new picture rate (asked, or measured at the camera)
    skipped_inactive: int = 0  # frames not encoded because nobody subscribes


class Transcoder(Protocol):
    """What the stage needs of a transcoder (:class:`MjpegTranscoder` is one)."""

    def transcode(self, jpeg: bytes, capture_ns: int | None = None) -> EncodedFrame:
        """One JPEG in, one access unit out (raises MediaError for a JPEG that does not decode)."""
        ...

    def set_bitrate(self, kbps: int) -> None:
        """Live bitrate (kbit/s)."""
        ...

    def set_keyframe_interval(self, frames: int) -> None:
        """Live periodic IDR interval."""
        ...

    def set_vbv(self, kbit: int) -> None:
        """A new VBV buffer (kbit, 0 = default), in force from the next IDR."""
        ...

    def request_idr(self) -> None:
        """The next frame out is an IDR."""
        ...


class H264Stage:
    """One shared H.264 stream (see the module docstring); thread-safe (frames arrive on the reader thread,
    activity and IDR requests from ROS callbacks)."""

    def __init__(
        self,
        settings: Callable[[], H264Settings],
        publish: Callable[[EncodedFrame], None],
        *,
        transcoder_factory: Callable[[H264Settings], Transcoder] | None = None,
        on_problem: Callable[[str], None] | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        """``settings()`` is read on every frame; ``publish`` is called on the feeding thread. The default
        ``transcoder_factory`` is :class:`~axis_ptz_ros2.media.transcoder.MjpegTranscoder`; without a usable PyAV
        the stage says so once through ``on_problem`` and transcodes nothing (pass-through needs no PyAV)."""
        self._settings = settings
        self._publish = publish
        self._factory = transcoder_factory or _mjpeg_transcoder
        self._unavailable = ""  # why this stage cannot transcode (PyAV missing or too old), said once
        self._on_problem = on_problem
        self._clock = clock
        self._lock = threading.Lock()
        self._active = False
        self._transcoder: Transcoder | None = None
        self._opened_with: H264Settings | None = None
        self._applied_kbps = 0  # the bitrate the encoder targets now
        self._applied_vbv = 0  # the VBV buffer (kbit) last given to the encoder
        self._opened_kbps = 0  # the bitrate (VBV maxrate) it was opened with: live changes up to it need no re-open
        self._idr_pending = False
        self._last_idr_request = -1e18
        self._idr_again_at = 0.0  # a new subscriber's second IDR is due then (0: none)
        self._pts = 0
        self._arrivals: deque[int] = deque(maxlen=RATE_WINDOW)
        self._consumer_errors = ConsumerCounts()
        self._params = annexb.ParameterSetTracker()
        self.stats = StageStats()

    # -- control (any thread) --------------------------------------------------------------------------------
    @property
    def active(self) -> bool:
        """Whether frames are being encoded (someone subscribes to the H.264 topics)."""
        return self._active

    @property
    def encoder_open(self) -> bool:
        """Whether a transcoder (an encoder) exists right now."""
        return self._transcoder is not None

    @property
    def keyframe_interval(self) -> int:
        """The keyframe interval (frames) the open encoder has, at the rate it runs at (0 = none open)."""
        have = self._opened_with
        return 0 if have is None else have.effective_keyframe_interval

    def set_active(self, active: bool) -> None:
        """Start (the first frame is an IDR) or stop encoding; stopping drops the encoder."""
        with self._lock:
            if active == self._active:
                return
            self._active = active
            if not active:
                self._transcoder = None
                self._opened_with = None
            self._idr_pending = True

    def request_idr(self) -> bool:
        """Ask for an IDR (a new subscriber, a consumer that lost sync); False when one was granted less than
        :data:`IDR_MIN_INTERVAL_S` ago (the request is then kept and honoured when the interval ends)."""
        with self._lock:
            self._idr_pending = True
            return self._clock() - self._last_idr_request >= IDR_MIN_INTERVAL_S

    def new_subscriber(self) -> None:
        """A new subscriber needs a start point: an IDR now (:meth:`request_idr`) and another
        :data:`NEW_SUBSCRIBER_IDR_AGAIN_S` later, for when it learns of the publisher only after the first."""
        with self._lock:
            self._idr_pending = True
            self._idr_again_at = self._clock() + NEW_SUBSCRIBER_IDR_AGAIN_S

    def _idr_again_due(self) -> None:
        """Turn a new subscriber's second IDR into a request once it is due; call with the lock held."""
        if self._idr_again_at and self._clock() >= self._idr_again_at:
            self._idr_again_at = 0.0
            self._idr_pending = True

    def consumer_errors(self, consumer: str, errors: int) -> bool:
        """A consumer reports ``errors`` access units it could not show over its report's window: ask for an IDR
        (:meth:`request_idr`) when that count grew since its last report (new losses); True when one was asked."""
        with self._lock:
            if errors <= 0:
                self._consumer_errors.forget(consumer)
                return False
            grown = self._consumer_errors.grew(consumer, errors, first=0)
        if not grown:
            return False
        self.request_idr()
        return True

    @property
    def idr_wanted(self) -> bool:
        """An IDR has been asked for and not yet given (for a source that makes its own: RTSP)."""
        with self._lock:
            self._idr_again_due()
            return self._idr_pending and self._clock() - self._last_idr_request >= IDR_MIN_INTERVAL_S

    def idr_sent(self) -> None:
        """A source that makes its own IDRs has asked for one (the rate limit counts from now)."""
        with self._lock:
            self._idr_pending = False
            self._last_idr_request = self._clock()
            self.stats.idr_requests += 1

    def discontinuity(self) -> None:
        """The source restarted (the reader reconnected): the next frame is an IDR, at once."""
        with self._lock:
            self._idr_pending = True
            self._last_idr_request = -1e18

    # -- frames (the reader thread) ----------------------------------------------------------------------------
    def on_jpeg(self, jpeg: bytes, arrival_ns: int) -> EncodedFrame | None:
        """Transcode one JPEG of the camera and publish it; None while inactive or when it does not decode."""
        problem = unavailable = ""
        with self._lock:
            if not self._active or self._unavailable:
                self.stats.skipped_inactive += 1
                return None
            self._arrivals.append(arrival_ns)
            try:
                transcoder = self._prepare(self._at_input_rate(self._settings()))
            except PyAvUnavailableError as err:  # said once; the MJPEG topics are not affected
                self._unavailable = unavailable = f"H.264 transcoding is off (MJPEG goes on): {err}"
            else:
                try:
                    frame = transcoder.transcode(jpeg, arrival_ns)  # stamped as the JPEG: its arrival
                    want = self._opened_with
                    if want is not None and want.bitrate_kbps != self._applied_kbps:  # the encoder is open now
                        transcoder.set_bitrate(want.bitrate_kbps)
                        self._applied_kbps = want.bitrate_kbps
                    if want is not None and want.vbv_kbit != self._applied_vbv:
                        transcoder.set_vbv(want.vbv_kbit)
                        self._applied_vbv = want.vbv_kbit
                except MediaError as err:
                    self.stats.bad_inputs += 1
                    problem = str(err)
        if unavailable:
            self._problem(unavailable)
            return None
        if problem:
            self._problem(f"H.264: frame dropped: {problem}")
            return None
        return self._emit(frame, arrival_ns)

    def on_access_unit(self, frame: EncodedFrame, stamp_ns: int) -> EncodedFrame | None:
        """Seam for sources that deliver H.264 (RTSP pass-through): publish one access unit as it came, with
        SPS/PPS put in front of an IDR that lacks them. None while inactive or when it is malformed.

        Such a source makes its own IDRs: whoever drives it reads :attr:`idr_wanted` (and calls
        :meth:`idr_sent` once it has asked the camera, e.g. RTSP ``SET_PARAMETER`` ``Renew-Stream: yes``)."""
        with self._lock:
            if not self._active:
                self.stats.skipped_inactive += 1
                return None
            try:
                data = self._params.process(frame.data)
            except BitstreamError as err:
                self.stats.bad_inputs += 1
                problem = str(err)
            else:
                problem = ""
        if problem:
            self._problem(f"H.264: access unit dropped: {problem}")
            return None
        return self._emit(replace(frame, data=data), stamp_ns)

    @property
    def input_fps(self) -> float | None:
        """The camera's picture rate as measured (None before :data:`RATE_WINDOW` JPEGs)."""
        if len(self._arrivals) < RATE_WINDOW:
            return None
        t = list(self._arrivals)
        intervals = sorted(b - a for a, b in zip(t, t[1:], strict=False))
        median = intervals[len(intervals) // 2]
        return 1e9 / median if median > 0 else None

    # -- internals ---------------------------------------------------------------------------------------------
    def _at_input_rate(self, want: H264Settings) -> H264Settings:
        """``want`` with the fps the encoder is to run at (see the module docstring); call with the lock held."""
        asked = want.fps
        measured = self.input_fps
        fps = asked if measured is None else max(1, min(asked, round(measured)))
        have = self._opened_with
        if have is not None and have.fps <= asked and abs(have.fps - fps) < RATE_REOPEN_FPS:
            fps = have.fps  # close enough: no re-open (an IDR) for a rate that wobbles
        return want if fps == want.fps else replace(want, fps=fps)

    def _prepare(self, want: H264Settings) -> Transcoder:
        """The transcoder for ``want`` (made, re-made, or adjusted live); call with the lock held."""
        have = self._opened_with
        t = self._transcoder
        if (
            t is None
            or have is None
            or (have.preset, have.fps, have.profile, have.refresh)
            != (want.preset, want.fps, want.profile, want.refresh)
            or want.max_bitrate_kbps > self._opened_kbps  # (a ceiling above the VBV maxrate: re-opened once, at it)
        ):
            for_fps = t is not None and have is not None and have.preset == want.preset and have.fps != want.fps
            opening = want.opening()
            t = self._factory(opening)
            self._transcoder = t
            self._applied_kbps = opening.bitrate_kbps  # opened at the ceiling; lowered after the first frame
            self._applied_vbv = opening.vbv_kbit
            self._opened_kbps = self._applied_kbps
            self.stats.encoder_opens += 1
            self.stats.fps_reopens += int(for_fps)
            self._idr_pending = False  # a new encoder starts with an IDR
            self._last_idr_request = self._clock()
        else:
            if have.effective_keyframe_interval != want.effective_keyframe_interval:
                t.set_keyframe_interval(want.effective_keyframe_interval)  # intra refresh: re-opened (an IDR)
        self._opened_with = want
        now = self._clock()
        self._idr_again_due()
        if self._idr_pending and now - self._last_idr_request >= IDR_MIN_INTERVAL_S:
            t.request_idr()
            self._idr_pending = False
            self._last_idr_request = now
            self.stats.idr_requests += 1
        return t

    def _emit(self, frame: EncodedFrame, stamp_ns: int) -> EncodedFrame:
        with self._lock:
            pts = self._pts
            self._pts += 1
            self.stats.frames += 1
            self.stats.idrs += int(frame.keyframe)
        out = replace(frame, pts=pts, capture_ns=stamp_ns)  # the stage's pts, the frame's capture stamp
        self._publish(out)
        return out

    def _problem(self, text: str) -> None:
        if self._on_problem is not None:
            self._on_problem(text)


def _mjpeg_transcoder(settings: H264Settings) -> Transcoder:
    """The default transcoder, imported on first use (it needs PyAV: :mod:`axis_ptz_ros2.media.pyav`)."""
    from axis_ptz_ros2.media.transcoder import MjpegTranscoder  # noqa: PLC0415 - raises PyAvUnavailableError

    return MjpegTranscoder(settings)
