"""The H.264 encoder's settings: one type from the stream node's request to libx264 (ROS-free, PyAV-free).

:class:`H264Settings` is what the stream node's ``h264_*`` parameters ask for
(:attr:`~axis_ptz_ros2.streaming.video_types.VideoSettings.h264`), what the video controller tells the H.264 stage
to do now (the bitrate the budgets leave, the ceiling, the VBV buffer, the rate in effect), and what the
transcoder, the encoder and the simulated camera's RTSP encoder are built from; the picture size is an argument
of the encoder (``H264Encoder(settings, width, height)``), not a setting. Bounds and defaults come from the one
table, :mod:`.limits`; every field is checked when an object is made (:class:`~.errors.EncoderError` naming the
field and its bounds), so a settings object that exists is one libx264 opens with.

One unit convention: kbit/s for bitrates, kbit for the VBV buffer. libx264 (through PyAV) takes bit/s and bits:
:attr:`H264Settings.bitrate_bps` and :attr:`H264Settings.vbv_bits` are the one place they are converted.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from axis_ptz_ros2.media.errors import EncoderError
from axis_ptz_ros2.media.limits import (
    DEFAULT_BITRATE_KBPS,
    DEFAULT_FPS,
    DEFAULT_KEYFRAME_INTERVAL,
    DEFAULT_MAX_BITRATE_KBPS,
    DEFAULT_PRESET,
    DEFAULT_PROFILE,
    DEFAULT_REFRESH,
    ENCODER_BITRATE_RANGE_KBPS,
    ENCODER_FPS_RANGE,
    KEYFRAME_RANGE,
    MAX_DIMENSION,
    MIN_VBV_KBIT,
    PRESETS,
    PROFILES,
    REFRESH_MODES,
    REPORTED_WAVE_RANGE,
    THREADS_RANGE,
)


@dataclass(frozen=True, slots=True)
class H264Settings:
    """What the H.264 encoder is to do (see the module docstring); every field checked when the object is made.

    A request (``VideoSettings.h264``) says the bitrate without feedback and the ceiling a clear link may raise it
    to; the video controller's target says the bitrate now and the ceiling to expect, which the stage opens the
    encoder at (:meth:`opening`). The encoder itself reads ``bitrate_kbps`` and ignores ``max_bitrate_kbps``.
    A camera-like stream (the simulator's) says ``profile="baseline"``, ``refresh="idr"``."""

    bitrate_kbps: int = DEFAULT_BITRATE_KBPS  # kbit/s: the target (a request's: without feedback)
    max_bitrate_kbps: int = DEFAULT_MAX_BITRATE_KBPS  # kbit/s: the ceiling; at or below bitrate_kbps: no higher
    keyframe_interval: int = DEFAULT_KEYFRAME_INTERVAL  # frames per intra-refresh wave (idr: between periodic IDRs)
    preset: str = DEFAULT_PRESET  # libx264 preset, one of PRESETS
    fps: int = DEFAULT_FPS  # pictures/s the encoder runs at
    vbv_kbit: int = 0  # kbit: the VBV buffer (bounds the largest picture, an IDR); 0 = bitrate × VBV_BUFFER_S
    profile: str = DEFAULT_PROFILE  # one of PROFILES
    refresh: str = DEFAULT_REFRESH  # one of REFRESH_MODES: x264's intra refresh (IDRs on request), or periodic IDRs
    threads: int = 1  # libx264 threads (THREADS_RANGE)
    #: x264's psychovisual optimisations (psy-rd, psy-trellis; x264's own default is on). Off, x264 codes the blocks
    #: the intra-refresh column forces at the intra quantiser, not the P one: against the simulated 214's picture
    #: before noise, +0.7 dB at 1500 and +1.3 dB at 1000 kbit/s with superfast, for no CPU
    #: (``bench/encoder_tradeoff.py``)
    psy: bool = False
    #: frames per intra-refresh wave while :attr:`long_wave` (0: off, the wave stays :attr:`gop_frames`)
    reported_wave: int = 0
    #: the intra-refresh wave may be :attr:`reported_wave` (:attr:`effective_keyframe_interval`): every H.264 viewer
    #: reports its losses on ``video/feedback`` (each asks for an IDR) and none has lost any lately; decided by the
    #: stream node (:meth:`~axis_ptz_ros2.streaming.long_wave.LongWave.allowed`)
    long_wave: bool = False

    def __post_init__(self) -> None:
        low, high = ENCODER_BITRATE_RANGE_KBPS
        _check_int("bitrate", self.bitrate_kbps, low, high, "kbit/s")
        _check_int("max bitrate", self.max_bitrate_kbps, low, high, "kbit/s")
        _check_int("keyframe interval", self.keyframe_interval, *KEYFRAME_RANGE, "frames")
        _check_int("reported wave", self.reported_wave, *REPORTED_WAVE_RANGE, "frames (0: off)")
        _check_int("fps", self.fps, *ENCODER_FPS_RANGE, "pictures/s")
        _check_int("threads", self.threads, *THREADS_RANGE, "")
        if not isinstance(self.psy, bool):
            raise EncoderError(f"psy must be True or False, got {self.psy!r}")
        if type(self.vbv_kbit) is not int or self.vbv_kbit != 0:  # 0 (the int): the default buffer
            _check_int("VBV buffer", self.vbv_kbit, MIN_VBV_KBIT, high, "kbit (or 0: the default)")
        for name, value, allowed in (
            ("preset", self.preset, PRESETS),
            ("profile", self.profile, PROFILES),
            ("refresh", self.refresh, REFRESH_MODES),
        ):
            if value not in allowed:
                raise EncoderError(f"{name} must be one of {', '.join(allowed)}; got {value!r}")

    @property
    def bitrate_bps(self) -> int:
        """The bitrate in bit/s, as libx264 takes it."""
        return self.bitrate_kbps * 1000

    @property
    def vbv_bits(self) -> int:
        """The VBV buffer in bits, as libx264 takes it (0 = the encoder's default)."""
        return self.vbv_kbit * 1000

    @property
    def gop_frames(self) -> int:
        """Frames between periodic IDRs (``idr``; a camera's own H.264: its GOP), or per intra-refresh wave while a
        viewer does not report its losses: ``keyframe_interval``, at most one second of frames. Such a viewer
        (rviz, Foxglove, a plain subscription) heals from a lost access unit only by the refresh, so the wave is
        kept short for it."""
        return min(self.keyframe_interval, self.fps)

    @property
    def effective_keyframe_interval(self) -> int:
        """The encoder's keyframe interval in frames: with intra refresh, :attr:`reported_wave` set and
        :attr:`long_wave` (every viewer reports its losses, so each asks for an IDR and the wave need not heal
        anyone; none lost any lately) :attr:`reported_wave`; otherwise :attr:`gop_frames`. A longer wave spends
        fewer bits on intra blocks (a 4 s wave against 1 s, ``bench/encoder_tradeoff.py``: +0.3 dB at 1000 kbit/s,
        none at 1500 with :attr:`psy` off; +0.5 / +1.0 dB with it on) but makes each IDR's blur last longer
        (docs/weak-link.md)."""
        if self.refresh == "intra" and self.long_wave and self.reported_wave > 0:
            return self.reported_wave
        return self.gop_frames

    def opening(self) -> H264Settings:
        """What the stage opens an encoder with for this target: at the ceiling (``max(bitrate_kbps,
        max_bitrate_kbps)``, the VBV maxrate, so a budget that moves under it changes the bitrate live: x264
        cannot raise maxrate on an open encoder, that would re-open it, with an IDR, on every step up), and the
        keyframe interval that applies (:attr:`effective_keyframe_interval`)."""
        return replace(
            self,
            bitrate_kbps=max(self.bitrate_kbps, self.max_bitrate_kbps),
            keyframe_interval=self.effective_keyframe_interval,
        )


def check_size(width: int, height: int) -> None:
    """Raise :class:`EncoderError` unless ``width`` × ``height`` is a picture size the encoder takes."""
    for name, v in (("width", width), ("height", height)):
        if isinstance(v, bool) or not isinstance(v, int) or not 16 <= v <= MAX_DIMENSION or v % 2:
            raise EncoderError(f"{name} must be an even number of pixels in 16…{MAX_DIMENSION}, got {v!r}")


def _check_int(name: str, value: object, low: int, high: int, unit: str) -> None:
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise EncoderError(f"{name} must be {low}…{high} {unit}".rstrip() + f", got {value!r}")
