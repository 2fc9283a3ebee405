"""Low-latency H.264 encoding with libx264 through PyAV (ROS-free).

What viewers and a weak link need, and how it is had (facts in docs/…/h264.md, checked with PyAV 18):

- No B-frames, ``tune=zerolatency``: the access unit for frame k comes out of the same :meth:`H264Encoder.encode`
  call (one in, one out). Profile :attr:`H264Settings.profile`: ``baseline`` (x264's Constrained Baseline) or
  ``high`` (CABAC, 8x8 transform; without B-frames nothing is reordered either).
- No global header: libx264 then repeats SPS/PPS in front of every IDR, which stock decoders need.
- VBV at open (``maxrate`` = bitrate, ``bufsize`` = ``vbv_kbit`` or bitrate × :data:`VBV_BUFFER_S`): the rate
  holds within a few frames (an IDR is at most about the VBV buffer: ~0.15 s of the bitrate, 19 kB at 1 Mbit/s,
  75 ms on a 2 Mbit/s link), and a live ``bit_rate`` change takes effect (x264 cannot turn VBV on later). PyAV
  can change neither ``maxrate`` nor ``bufsize`` on an open encoder (``max_bit_rate`` is read-only, there is no
  ``rc_buffer_size``): a bitrate above the one opened with re-opens the encoder at once (its next frame is an
  IDR); a new VBV buffer (:meth:`H264Encoder.set_vbv`) re-opens it at the next IDR it makes anyway (periodic or
  requested), with the same ``maxrate``, so a buffer that follows the link costs no extra IDR. Until then the
  buffer opened with stays: x264 keeps it when only ``bit_rate`` is lowered (opened at 1000 kbit/s and lowered
  to 600, its IDRs stayed 86 kbit against 73 kbit for one opened at 600). Every open, a re-open too, is at
  ``maxrate`` with the target set live after it: x264 follows a live bitrate only when it opened as CBR
  (``maxrate`` <= bitrate); opened under a higher ``maxrate`` it keeps the bitrate it opened with for good (re-opened
  at 275 kbit/s under a 1350 ceiling, a live 1000 kbit/s gave 280; on the two-host 1 Mbit/s link x264 sent 310
  kbit/s under a budget climbing to 1105).
- Keyframes: x264's own are off (``scenecut=0``); this class forces an IDR on request (``forced-idr=1`` +
  ``PictureType.I``) and, with :attr:`H264Settings.refresh` ``idr``, every ``keyframe_interval`` frames (x264's
  ``keyint=infinite``), so the interval is live too. With ``intra`` x264's periodic intra refresh
  (``intra-refresh=1``, ``keyint`` = the interval) sweeps a column of intra blocks across the picture instead, one
  wave per interval, and no IDR follows the first but the ones requested: no picture is an IDR squeezed into the
  VBV buffer, so the picture does not blur once an interval (issue 39). libx264 flags each wave's recovery point
  key (a P-picture with SPS/PPS and a recovery-point SEI); :attr:`EncodedFrame.keyframe` is True for IDRs only,
  where a decoder can start. A new interval re-opens x264 then (it takes ``keyint`` only when it opens), with an IDR.
- Adaptive quantisation off (``aq-mode=0``, what x264's ``tune=psnr`` does to AQ): x264's default AQ moves bits
  from detailed blocks (edges, text) to flat ones, for the look of flat areas; an operator reading labels needs
  the detail. On the simulated 214's noisy compression-0 pictures at 1000 kbit/s it measured +2.1 dB PSNR (median
  35.8 → 37.9 dB against the view before noise) and ~1 ms less x264 time per 704×576 frame (README, "H.264 encoder
  settings").
- Psychovisual optimisations off (``psy=0``, the rest of what ``tune=psnr`` does; :attr:`H264Settings.psy`): x264
  then codes the blocks the intra-refresh column forces at the intra quantiser, not the P one: +0.7 dB at 1500 and
  +1.3 dB at 1000 kbit/s on the same pictures, for no CPU (docs/weak-link.md, "x264's psychovisual optimisations
  off").
"""

from __future__ import annotations

from dataclasses import replace
from fractions import Fraction

from axis_ptz_ros2.media import pyav

pyav.require()  # raises PyAvUnavailableError naming the PyAV needed and how to get it

import av
import av.error
import numpy as np
import numpy.typing as npt
from av.video.frame import PictureType

from axis_ptz_ros2.media import annexb
from axis_ptz_ros2.media.errors import EncoderError
from axis_ptz_ros2.media.frame import EncodedFrame
from axis_ptz_ros2.media.h264_settings import H264Settings, check_size
from axis_ptz_ros2.media.limits import MIN_VBV_KBIT, VBV_BUFFER_S, VBV_REOPEN_SLACK

U8Array = npt.NDArray[np.uint8]


class H264Encoder:
    """One libx264 encoder for pictures of one size: frames in (BGR or PyAV frames), one Annex B access unit out per
    frame. Built from :class:`~.h264_settings.H264Settings` (``max_bitrate_kbps`` is the stage's, not read here)."""

    def __init__(self, settings: H264Settings, width: int, height: int) -> None:
        check_size(width, height)
        self._settings = settings
        self.width, self.height = width, height
        self._pts = 0
        self._since_idr = 0
        self._idr_requested = True
        self._reopen = False
        self._reopen_at_idr = False  # a new VBV buffer waits for the next IDR
        self.reopens = 0
        self._codec_string: str | None = None
        self._maxrate = settings.bitrate_bps
        self._bufsize = 0
        self._ctx = self._open(settings)

    # ---- parameters ----------------------------------------------------------------------------------------
    @property
    def settings(self) -> H264Settings:
        """The settings in force (the live changes included)."""
        return self._settings

    @property
    def opened_max_bitrate_bps(self) -> int:
        """The VBV ``maxrate`` (bit/s) the encoder is open with (a live bitrate up to this needs no re-open)."""
        return self._maxrate

    @property
    def opened_vbv_bits(self) -> int:
        """The VBV buffer (bits) the encoder is open with."""
        return self._bufsize

    @property
    def codec_string(self) -> str | None:
        """``avc1.PPCCLL`` of the SPS the last IDR carried (WebCodecs ``configure``); None before the first frame."""
        return self._codec_string

    def set_bitrate(self, kbps: int) -> None:
        """Change the target bitrate (kbit/s) from the next frame on (live up to the opened maxrate, else re-open)."""
        self._settings = replace(self._settings, bitrate_kbps=kbps)
        if self._settings.bitrate_bps > self._maxrate:
            self._reopen = True
        else:
            self._ctx.bit_rate = self._settings.bitrate_bps

    def set_vbv(self, kbit: int) -> None:
        """A new VBV buffer (kbit; 0 = bitrate × :data:`VBV_BUFFER_S`), in force from the next IDR on (see the
        module docstring): one within :data:`VBV_REOPEN_SLACK` of the open one changes nothing."""
        self._settings = replace(self._settings, vbv_kbit=kbit)
        want = self._bufsize_for(self._settings, self._maxrate)
        self._reopen_at_idr = abs(want - self._bufsize) > VBV_REOPEN_SLACK * self._bufsize

    def set_keyframe_interval(self, frames: int) -> None:
        """Periodic IDR every ``frames`` frames from now on; with intra refresh, a refresh wave of ``frames``
        frames (x264 takes it only when it opens: a new one re-opens the encoder, with an IDR)."""
        old = self._settings.keyframe_interval
        self._settings = replace(self._settings, keyframe_interval=frames)
        if self._settings.refresh == "intra" and frames != old:
            self._reopen = True

    def request_idr(self) -> None:
        """Make the next encoded frame an IDR (with SPS/PPS)."""
        self._idr_requested = True

    # ---- encoding ------------------------------------------------------------------------------------------
    def encode_bgr(self, image: U8Array, capture_ns: int | None = None) -> EncodedFrame:
        """Encode one BGR image of the configured size."""
        w, h = self.width, self.height
        if image.dtype != np.uint8 or image.shape != (h, w, 3):
            raise EncoderError(f"expected a {w}x{h} BGR uint8 image, got shape {image.shape} dtype {image.dtype}")
        return self.encode(av.VideoFrame.from_ndarray(image, format="bgr24"), capture_ns)

    def encode(self, frame: av.VideoFrame, capture_ns: int | None = None) -> EncodedFrame:
        """Encode one PyAV frame of the configured size (any pixel format; converted to yuv420p)."""
        c = self._settings
        if (frame.width, frame.height) != (self.width, self.height):
            raise EncoderError(f"frame is {frame.width}x{frame.height}, the encoder {self.width}x{self.height}")
        if self._reopen:
            self._ctx = self._open(c, self._maxrate)  # a new wave keeps the ceiling: no re-open per step up
            self._reopen = False
            self._reopen_at_idr = False
            self.reopens += 1
            self._idr_requested = True
        key = self._idr_requested or (c.refresh == "idr" and self._since_idr >= c.keyframe_interval)
        if key and self._reopen_at_idr:  # an IDR anyway: the new VBV buffer costs none
            self._ctx = self._open(c, self._maxrate)
            self._reopen_at_idr = False
            self.reopens += 1
        frame.pts = self._pts
        frame.time_base = self._ctx.time_base
        frame.pict_type = PictureType.I if key else PictureType.NONE
        try:
            packets = self._ctx.encode(frame)
        except av.error.FFmpegError as err:
            raise EncoderError(f"libx264 refused the frame: {err}") from err
        if len(packets) != 1:
            raise EncoderError(f"libx264 returned {len(packets)} packets for one frame (expected 1)")
        data = bytes(packets[0])
        # an IDR, not what libx264 flags key: with intra refresh it flags each wave's recovery point (a P-picture
        # with SPS/PPS and a recovery-point SEI) key too, and no decoder can start there
        keyframe = annexb.is_idr(data)
        out = EncodedFrame(data, keyframe, self._pts, self.width, self.height, capture_ns)
        self._pts += 1
        if keyframe:
            sps = annexb.find_sps(data)
            if sps is None:
                raise EncoderError("libx264 made an IDR without an SPS (opened with a global header?)")
            self._codec_string = sps.codec_string
            self._idr_requested = False
            self._since_idr = 1
        else:
            self._since_idr += 1
        return out

    # ---- internals -----------------------------------------------------------------------------------------
    @staticmethod
    def _bufsize_for(c: H264Settings, maxrate: int) -> int:
        """The VBV buffer in bits for ``c`` and VBV ``maxrate`` (bit/s)."""
        return c.vbv_bits or max(int(maxrate * VBV_BUFFER_S), MIN_VBV_KBIT * 1000)

    def _open(self, c: H264Settings, maxrate: int = 0) -> av.VideoCodecContext:
        """A new libx264 context for ``c``, VBV ``maxrate`` (bit/s) = ``maxrate`` (0: the bitrate) and the buffer
        :meth:`_bufsize_for`."""
        maxrate = max(maxrate, c.bitrate_bps)
        bufsize = self._bufsize_for(c, maxrate)
        ctx = av.VideoCodecContext.create("libx264", "w")
        ctx.width = self.width
        ctx.height = self.height
        ctx.pix_fmt = "yuv420p"
        ctx.time_base = Fraction(1, c.fps)
        ctx.framerate = Fraction(c.fps, 1)
        # opened at maxrate (x264's CBR), the target set live below: x264 follows a live bitrate only in the mode it
        # opened in as CBR (maxrate <= bitrate); opened with maxrate above the bitrate it keeps that bitrate for good
        # ("We don't support changing the ABR bitrate right now", x264's ratecontrol.c)
        ctx.bit_rate = maxrate
        ctx.max_b_frames = 0
        ctx.thread_count = c.threads
        # periodic IDRs are this class's (keyint infinite); intra refresh is x264's, one wave per keyframe interval
        keyint = f"keyint={c.keyframe_interval}:intra-refresh=1" if c.refresh == "intra" else "keyint=infinite"
        psy = "" if c.psy else ":psy=0"  # (H264Settings.psy)
        ctx.options = {
            "preset": c.preset,
            "tune": "zerolatency",
            "profile": c.profile,
            "forced-idr": "1",
            "maxrate": str(maxrate),
            "bufsize": str(bufsize),
            "x264-params": f"{keyint}:min-keyint=1:scenecut=0:bframes=0:aq-mode=0{psy}",
        }
        try:
            ctx.open()
        except av.error.FFmpegError as err:
            raise EncoderError(f"libx264 did not open {self.width}x{self.height} with {c}: {err}") from err
        ctx.bit_rate = c.bitrate_bps  # live from the first frame on (libavcodec reconfigures x264 before each frame)
        self._maxrate, self._bufsize = maxrate, bufsize
        return ctx
