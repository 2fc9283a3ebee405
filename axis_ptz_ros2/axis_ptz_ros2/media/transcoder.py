"""MJPEG → H.264 for cameras that only stream MJPEG (the 214), ROS-free.

One :class:`MjpegTranscoder` per camera stream, shared by every H.264 subscriber: JPEG bytes in (the camera's
compression 0), one :class:`~axis_ptz_ros2.media.frame.EncodedFrame` out. A JPEG of another size re-opens the
encoder (its first frame is an IDR with the new SPS); a JPEG that does not decode raises
:class:`~axis_ptz_ros2.media.errors.TranscodeError` and leaves the encoder as it was.

JPEG decoding: ``pyav`` (the default: FFmpeg's mjpeg decoder, whose 4:2:0 planes only change range, full →
limited, on the way to the encoder) or ``cv2`` (libjpeg-turbo to BGR, then OpenCV's BGR→I420, which resamples
the chroma twice: up to BGR, then down by point sampling); ``bench/bench_transcode.py`` measures both (about the
same CPU here). The colour path matters as much as the bitrate: against the simulated camera's picture before
noise and compression, the ``cv2`` path alone (no encoding) caps a decoded picture at 37.6 dB, the ``pyav`` path
at 39.0 dB (``H264Decoder``'s conversion; the JPEG itself is 39.3 dB), and transcoded at 1000 kbit/s the
``pyav`` path is 1.4 dB better.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Final, Literal

from axis_ptz_ros2.media import pyav

pyav.require()  # raises PyAvUnavailableError naming the PyAV needed and how to get it

import av
import av.error
import cv2
import numpy as np

from axis_ptz_ros2.media import annexb
from axis_ptz_ros2.media.encoder import H264Encoder
from axis_ptz_ros2.media.errors import EncoderError, TranscodeError
from axis_ptz_ros2.media.frame import EncodedFrame
from axis_ptz_ros2.media.h264_settings import H264Settings

JpegDecoder = Literal["cv2", "pyav"]
JPEG_DECODERS: Final = ("cv2", "pyav")
#: the JPEG decoder the stream node uses (see the module docstring)
DEFAULT_JPEG_DECODER: Final[JpegDecoder] = "pyav"


class MjpegTranscoder:
    """JPEG bytes → H.264 access units, one encoder re-opened only when the picture size changes (the size comes
    from each JPEG; everything else from the :class:`~.h264_settings.H264Settings`). ``jpeg_decoder``: see the
    module docstring; ``stamp_sei``: put the capture time in each access unit (our user-data SEI)."""

    def __init__(
        self,
        settings: H264Settings | None = None,
        *,
        jpeg_decoder: JpegDecoder = DEFAULT_JPEG_DECODER,
        stamp_sei: bool = True,
    ) -> None:
        if jpeg_decoder not in JPEG_DECODERS:
            raise EncoderError(f"jpeg_decoder must be one of {', '.join(JPEG_DECODERS)}; got {jpeg_decoder!r}")
        self._settings = settings or H264Settings()
        self.jpeg_decoder: Final = jpeg_decoder
        self.stamp_sei: Final = stamp_sei
        self._encoder: H264Encoder | None = None
        self._mjpeg: av.VideoCodecContext | None = None
        self.frames = 0
        self.bad_jpegs = 0
        self.encoder_opens = 0

    @property
    def settings(self) -> H264Settings:
        """The settings in force (the live changes included)."""
        return self._settings

    @property
    def size(self) -> tuple[int, int] | None:
        """(width, height) the encoder is open for; None before the first frame."""
        return None if self._encoder is None else (self._encoder.width, self._encoder.height)

    @property
    def codec_string(self) -> str | None:
        """``avc1.PPCCLL`` of the current stream (from its last IDR); None before the first frame."""
        return None if self._encoder is None else self._encoder.codec_string

    def set_bitrate(self, kbps: int) -> None:
        """The target bitrate (kbit/s) from the next frame on (:meth:`H264Encoder.set_bitrate`)."""
        self._settings = replace(self._settings, bitrate_kbps=kbps)
        if self._encoder is not None:
            self._encoder.set_bitrate(kbps)

    def set_vbv(self, kbit: int) -> None:
        """The encoder's VBV buffer (kbit, 0 = default), from its next IDR on (:meth:`H264Encoder.set_vbv`)."""
        self._settings = replace(self._settings, vbv_kbit=kbit)
        if self._encoder is not None:
            self._encoder.set_vbv(kbit)

    def set_keyframe_interval(self, frames: int) -> None:
        """The keyframe interval (frames) from now on (:meth:`H264Encoder.set_keyframe_interval`)."""
        self._settings = replace(self._settings, keyframe_interval=frames)
        if self._encoder is not None:
            self._encoder.set_keyframe_interval(frames)

    def request_idr(self) -> None:
        """The next frame out is an IDR (a new subscriber, or a viewer that lost sync)."""
        if self._encoder is not None:
            self._encoder.request_idr()

    def transcode(self, jpeg: bytes, capture_ns: int | None = None) -> EncodedFrame:
        """Decode one JPEG and encode it; the access unit carries ``capture_ns`` in an SEI when configured."""
        frame = self._decode_jpeg(jpeg)
        w, h = frame.width, frame.height
        if w % 2 or h % 2:
            self.bad_jpegs += 1
            raise TranscodeError(f"JPEG of odd size {w}x{h}: H.264 4:2:0 needs even sizes")
        enc = self._encoder
        if enc is None or (enc.width, enc.height) != (w, h):
            enc = H264Encoder(self._settings, w, h)
            self._encoder = enc
            self.encoder_opens += 1
        out = enc.encode(frame, capture_ns)
        self.frames += 1
        if self.stamp_sei and capture_ns is not None:
            out = replace(out, data=annexb.insert_capture_stamp(out.data, capture_ns))
        return out

    def _decode_jpeg(self, jpeg: bytes) -> av.VideoFrame:
        if self.jpeg_decoder == "cv2":
            bgr = cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR) if jpeg else None
            if bgr is None:
                self.bad_jpegs += 1
                raise TranscodeError(f"JPEG of {len(jpeg)} bytes does not decode")
            h, w = bgr.shape[:2]
            if w % 2 or h % 2:
                self.bad_jpegs += 1
                raise TranscodeError(f"JPEG of odd size {w}x{h}: H.264 4:2:0 needs even sizes")
            i420 = np.asarray(cv2.cvtColor(bgr, cv2.COLOR_BGR2YUV_I420), dtype=np.uint8)
            return av.VideoFrame.from_ndarray(i420, format="yuv420p")
        if self._mjpeg is None:
            self._mjpeg = av.VideoCodecContext.create("mjpeg", "r")
            self._mjpeg.thread_count = 1
        try:
            frames = self._mjpeg.decode(av.Packet(jpeg))
        except (av.error.FFmpegError, ValueError) as err:
            self.bad_jpegs += 1
            self._mjpeg = None  # a fresh decoder for the next JPEG
            raise TranscodeError(f"JPEG of {len(jpeg)} bytes does not decode: {err}") from err
        if len(frames) != 1:
            self.bad_jpegs += 1
            raise TranscodeError(f"JPEG of {len(jpeg)} bytes gave {len(frames)} pictures")
        # FFmpeg's JPEG pictures are full range (yuvj420p); H.264 viewers assume limited range.
        return frames[0].reformat(format="yuv420p", src_color_range="JPEG", dst_color_range="MPEG")
