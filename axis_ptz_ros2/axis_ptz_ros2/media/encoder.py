"""Low-latency H.264 encoding with libx264 through PyAV (ROS-free).

What viewers and a weak link need, and how it is had (facts in docs/…/h264.md, checked with PyAV 18):

- No B-frames, ``tune=zerolatency``: the access unit for frame k comes out of the same :meth:`H264Encoder.encode`
  call (one in, one out). Profile :attr:`EncoderConfig.profile`: ``baseline`` (x264's Constrained Baseline) or
  ``high`` (CABAC, 8x8 transform; without B-frames nothing is reordered either).
- No global header: libx264 then repeats SPS/PPS in front of every IDR, which stock decoders need.
- VBV at open (``maxrate`` = bitrate, ``bufsize`` = ``vbv_bits`` or bitrate × :data:`VBV_BUFFER_S`): the rate
  holds within a few frames (an IDR is at most about the VBV buffer: ~0.15 s of the bitrate, 19 kB at 1 Mbit/s,
  75 ms on a 2 Mbit/s link), and a live ``bit_rate`` change takes effect (x264 cannot turn VBV on later). PyAV
  can change neither ``maxrate`` nor ``bufsize`` on an open encoder (``max_bit_rate`` is read-only, there is no
  ``rc_buffer_size``): a bitrate above the one opened with re-opens the encoder at once (its next frame is an
  IDR); a new VBV buffer (:meth:`H264Encoder.set_vbv`) re-opens it at the next IDR it makes anyway (periodic or
  requested), with the same ``maxrate``, so a buffer that follows the link costs no extra IDR. Until then the
  buffer opened with stays: x264 keeps it when only ``bit_rate`` is lowered (opened at 1000 kbit/s and lowered
  to 600, its IDRs stayed 86 kbit against 73 kbit for one opened at 600).
- Keyframes: x264's own are off (``scenecut=0``); this class forces an IDR on request (``forced-idr=1`` +
  ``PictureType.I``) and, with :attr:`EncoderConfig.refresh` ``idr``, every ``keyframe_interval`` frames (x264's
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
"""

from __future__ import annotations

from dataclasses import dataclass, replace
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
from axis_ptz_ros2.media.limits import (
    DEFAULT_BITRATE_KBPS,
    DEFAULT_KEYFRAME_INTERVAL,
    DEFAULT_PRESET,
    DEFAULT_PROFILE,
    DEFAULT_REFRESH,
    MAX_BITRATE_BPS,
    MAX_DIMENSION,
    MAX_KEYFRAME_INTERVAL,
    MIN_BITRATE_BPS,
    MIN_VBV_BITS,
    PRESETS,
    PROFILES,
    REFRESH_MODES,
    VBV_BUFFER_S,
    VBV_REOPEN_SLACK,
)

U8Array = npt.NDArray[np.uint8]


@dataclass(frozen=True, slots=True)
class EncoderConfig:
    """Encoder parameters; every field is checked when the object is built. The defaults are the stream node's
    (:mod:`.limits`); a camera-like stream (the simulator's) says ``profile="baseline"``, ``refresh="idr"``."""

    width: int
    height: int
    fps: int = 30
    bitrate_bps: int = DEFAULT_BITRATE_KBPS * 1000
    keyframe_interval: int = DEFAULT_KEYFRAME_INTERVAL  # frames between periodic IDRs (intra: per refresh wave)
    preset: str = DEFAULT_PRESET
    threads: int = 1  # 1: one slice per picture, lowest CPU; more: sliced threads (lower latency at 1080p)
    vbv_bits: int = 0  # the VBV buffer (bits; bounds the largest picture); 0 = bitrate × VBV_BUFFER_S
    profile: str = DEFAULT_PROFILE  # one of PROFILES
    refresh: str = DEFAULT_REFRESH  # one of REFRESH_MODES: periodic IDRs, or x264's intra refresh (IDRs on request)

    def __post_init__(self) -> None:
        for name in ("width", "height"):
            v = getattr(self, name)
            if not isinstance(v, int) or not 16 <= v <= MAX_DIMENSION or v % 2:
                raise EncoderError(f"{name} must be an even number of pixels in 16…{MAX_DIMENSION}, got {v!r}")
        if not isinstance(self.fps, int) or not 1 <= self.fps <= 120:
            raise EncoderError(f"fps must be 1…120, got {self.fps!r}")
        check_bitrate(self.bitrate_bps)
        check_keyframe_interval(self.keyframe_interval)
        if self.preset not in PRESETS:
            raise EncoderError(f"preset must be one of {', '.join(PRESETS)}; got {self.preset!r}")
        if not isinstance(self.threads, int) or not 1 <= self.threads <= 16:
            raise EncoderError(f"threads must be 1…16, got {self.threads!r}")
        check_vbv(self.vbv_bits)
        if self.profile not in PROFILES:
            raise EncoderError(f"profile must be one of {', '.join(PROFILES)}; got {self.profile!r}")
        if self.refresh not in REFRESH_MODES:
            raise EncoderError(f"refresh must be one of {', '.join(REFRESH_MODES)}; got {self.refresh!r}")


def check_bitrate(bps: int) -> int:
    """``bps`` if it is an int in MIN_BITRATE_BPS…MAX_BITRATE_BPS, else :class:`EncoderError`."""
    if isinstance(bps, bool) or not isinstance(bps, int) or not MIN_BITRATE_BPS <= bps <= MAX_BITRATE_BPS:
        raise EncoderError(f"bitrate must be {MIN_BITRATE_BPS}…{MAX_BITRATE_BPS} bit/s, got {bps!r}")
    return bps


def check_vbv(bits: int) -> int:
    """``bits`` if it is 0 (the default buffer) or an int in MIN_VBV_BITS…MAX_BITRATE_BPS, else
    :class:`EncoderError`."""
    if (
        isinstance(bits, bool)
        or not isinstance(bits, int)
        or not (bits == 0 or MIN_VBV_BITS <= bits <= MAX_BITRATE_BPS)
    ):
        raise EncoderError(f"VBV buffer must be 0 (default) or {MIN_VBV_BITS}…{MAX_BITRATE_BPS} bits, got {bits!r}")
    return bits


def check_keyframe_interval(frames: int) -> int:
    """``frames`` if it is an int in 1…MAX_KEYFRAME_INTERVAL, else :class:`EncoderError`."""
    if isinstance(frames, bool) or not isinstance(frames, int) or not 1 <= frames <= MAX_KEYFRAME_INTERVAL:
        raise EncoderError(f"keyframe interval must be 1…{MAX_KEYFRAME_INTERVAL} frames, got {frames!r}")
    return frames


class H264Encoder:
    """One libx264 encoder: frames in (BGR or PyAV frames), one Annex B access unit out per frame."""

    def __init__(self, config: EncoderConfig) -> None:
        self._config = config
        self._pts = 0
        self._since_idr = 0
        self._idr_requested = True
        self._reopen = False
        self._reopen_at_idr = False  # a new VBV buffer waits for the next IDR
        self.reopens = 0
        self._codec_string: str | None = None
        self._maxrate = config.bitrate_bps
        self._bufsize = 0
        self._ctx = self._open(config)

    # ---- parameters ----------------------------------------------------------------------------------------
    @property
    def config(self) -> EncoderConfig:
        return self._config

    @property
    def opened_max_bitrate_bps(self) -> int:
        """The VBV ``maxrate`` the encoder is open with (a live bitrate up to this needs no re-open)."""
        return self._maxrate

    @property
    def opened_vbv_bits(self) -> int:
        """The VBV buffer (bits) the encoder is open with."""
        return self._bufsize

    @property
    def codec_string(self) -> str | None:
        """``avc1.PPCCLL`` of the SPS the last IDR carried (WebCodecs ``configure``); None before the first frame."""
        return self._codec_string

    def set_bitrate(self, bps: int) -> None:
        """Change the target bitrate from the next frame on (live up to the opened maxrate, else re-open)."""
        check_bitrate(bps)
        self._config = replace(self._config, bitrate_bps=bps)
        if bps > self._maxrate:
            self._reopen = True
        else:
            self._ctx.bit_rate = bps

    def set_vbv(self, bits: int) -> None:
        """A new VBV buffer (bits; 0 = bitrate × :data:`VBV_BUFFER_S`), in force from the next IDR on (see the
        module docstring): one within :data:`VBV_REOPEN_SLACK` of the open one changes nothing."""
        self._config = replace(self._config, vbv_bits=check_vbv(bits))
        want = self._bufsize_for(self._config, self._maxrate)
        self._reopen_at_idr = abs(want - self._bufsize) > VBV_REOPEN_SLACK * self._bufsize

    def set_keyframe_interval(self, frames: int) -> None:
        """Periodic IDR every ``frames`` frames from now on; with intra refresh, a refresh wave of ``frames``
        frames (x264 takes it only when it opens: a new one re-opens the encoder, with an IDR)."""
        old = self._config.keyframe_interval
        self._config = replace(self._config, keyframe_interval=check_keyframe_interval(frames))
        if self._config.refresh == "intra" and frames != old:
            self._reopen = True

    def request_idr(self) -> None:
        """Make the next encoded frame an IDR (with SPS/PPS)."""
        self._idr_requested = True

    # ---- encoding ------------------------------------------------------------------------------------------
    def encode_bgr(self, image: U8Array, capture_ns: int | None = None) -> EncodedFrame:
        """Encode one BGR image of the configured size."""
        c = self._config
        if image.dtype != np.uint8 or image.shape != (c.height, c.width, 3):
            raise EncoderError(
                f"expected a {c.width}x{c.height} BGR uint8 image, got shape {image.shape} dtype {image.dtype}"
            )
        return self.encode(av.VideoFrame.from_ndarray(image, format="bgr24"), capture_ns)

    def encode(self, frame: av.VideoFrame, capture_ns: int | None = None) -> EncodedFrame:
        """Encode one PyAV frame of the configured size (any pixel format; converted to yuv420p)."""
        c = self._config
        if (frame.width, frame.height) != (c.width, c.height):
            raise EncoderError(f"frame is {frame.width}x{frame.height}, the encoder {c.width}x{c.height}")
        if self._reopen:
            self._ctx = self._open(c)
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
        out = EncodedFrame(data, keyframe, self._pts, c.width, c.height, capture_ns)
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
    def _bufsize_for(c: EncoderConfig, maxrate: int) -> int:
        return c.vbv_bits or max(int(maxrate * VBV_BUFFER_S), MIN_VBV_BITS)

    def _open(self, c: EncoderConfig, maxrate: int = 0) -> av.VideoCodecContext:
        """A new libx264 context for ``c``, VBV ``maxrate`` = ``maxrate`` (0: the bitrate) and the buffer
        :meth:`_bufsize_for`."""
        maxrate = max(maxrate, c.bitrate_bps)
        bufsize = self._bufsize_for(c, maxrate)
        ctx = av.VideoCodecContext.create("libx264", "w")
        ctx.width = c.width
        ctx.height = c.height
        ctx.pix_fmt = "yuv420p"
        ctx.time_base = Fraction(1, c.fps)
        ctx.framerate = Fraction(c.fps, 1)
        ctx.bit_rate = c.bitrate_bps
        ctx.max_b_frames = 0
        ctx.thread_count = c.threads
        # periodic IDRs are this class's (keyint infinite); intra refresh is x264's, one wave per keyframe interval
        keyint = f"keyint={c.keyframe_interval}:intra-refresh=1" if c.refresh == "intra" else "keyint=infinite"
        ctx.options = {
            "preset": c.preset,
            "tune": "zerolatency",
            "profile": c.profile,
            "forced-idr": "1",
            "maxrate": str(maxrate),
            "bufsize": str(bufsize),
            "x264-params": f"{keyint}:min-keyint=1:scenecut=0:bframes=0:aq-mode=0",
        }
        try:
            ctx.open()
        except av.error.FFmpegError as err:
            raise EncoderError(f"libx264 did not open with {c}: {err}") from err
        self._maxrate, self._bufsize = maxrate, bufsize
        return ctx
