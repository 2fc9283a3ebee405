"""H.264 access units → BGR pictures (FFmpeg's h264 decoder through PyAV), ROS-free.

For the compressed→raw republisher and the link monitor. What it guarantees:

- Nothing comes out before an IDR (joining mid-GOP, or after :meth:`H264Decoder.mark_discontinuity`): a picture
  predicted from frames the decoder never saw would be garbage, not the scene.
- A decode error (corrupt or truncated access unit) is counted, the decoder is reset, and it waits for the next
  IDR; it never raises for bad input and never hands out an older picture again.
- An SPS with a new size (a resolution change) re-creates the decoder at that IDR.
- No frame threading: a picture comes out of the same :meth:`~H264Decoder.decode` call as its access unit.
- YUV 4:2:0 → BGR with the chroma interpolated to full resolution and exact rounding (swscale
  ``FULL_CHR_H_INT | ACCURATE_RND``): swscale's default repeats each chroma sample (its fast path), which
  alone cost 2.5 dB against the simulated camera's picture before noise and compression (38.4 instead of
  41.5 dB for a picture that was never encoded) for about 1 ms more per 704x576 picture.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

from axis_ptz_ros2.media import pyav

pyav.require()  # raises PyAvUnavailableError naming the PyAV needed and how to get it

import av
import av.error
import numpy as np
import numpy.typing as npt
from av.video.reformatter import Interpolation

from axis_ptz_ros2.media import annexb
from axis_ptz_ros2.media.errors import BitstreamError

U8Array = npt.NDArray[np.uint8]
#: swscale flags of the YUV → BGR conversion (see the module docstring)
TO_BGR: Final = Interpolation.BILINEAR | Interpolation.FULL_CHR_H_INT | Interpolation.ACCURATE_RND


@dataclass(frozen=True, slots=True)
class DecodedPicture:
    """One decoded picture: BGR, its size, whether it was an IDR and the capture time from our SEI.

    Not an :class:`axis_ptz_ros2.media.frame.EncodedFrame`: it holds pixels (what a decoder gives), not the
    bytes of an encoded frame, and goes to the raw republisher and the link monitor, not down the video path.
    """

    image: U8Array
    keyframe: bool
    capture_ns: int | None


@dataclass(slots=True)
class DecoderStats:
    """Counters since the decoder was made."""

    access_units: int = 0
    pictures: int = 0
    waiting_drops: int = 0  # access units dropped while waiting for an IDR
    decode_errors: int = 0  # malformed access units and errors FFmpeg reported
    resets: int = 0  # decoders re-created (errors, size changes)


class H264Decoder:
    """Annex B access units in, :class:`DecodedPicture` out (or None while waiting for an IDR)."""

    def __init__(self) -> None:
        self._ctx: av.VideoCodecContext | None = None
        self._size: tuple[int, int] | None = None
        self._waiting = True
        self.stats = DecoderStats()

    @property
    def waiting_for_idr(self) -> bool:
        return self._waiting

    @property
    def size(self) -> tuple[int, int] | None:
        """(width, height) of the current sequence, from its SPS."""
        return self._size

    def mark_discontinuity(self) -> None:
        """Frames were lost upstream: output nothing until the next IDR."""
        self._waiting = True

    def decode(self, access_unit: bytes) -> DecodedPicture | None:
        """Decode one access unit; None while waiting for an IDR or when it did not decode."""
        self.stats.access_units += 1
        try:
            nals = annexb.split_nal_units(access_unit)
            types = [nal[0] & 0x1F for nal in nals]
            idr = annexb.NalType.IDR in types
            sps = next((annexb.parse_sps(n) for n, t in zip(nals, types, strict=True) if t == annexb.NalType.SPS), None)
            stamp = annexb.extract_capture_stamp(access_unit) if annexb.NalType.SEI in types else None
        except BitstreamError:
            self._error()
            return None
        if self._waiting and not idr:
            self.stats.waiting_drops += 1
            return None
        if idr:
            if sps is not None and (sps.width, sps.height) != self._size:
                self._size = (sps.width, sps.height)
                self._reset()
            if self._ctx is None:
                if sps is None:  # an IDR without SPS/PPS, and no decoder that holds them
                    self._error()
                    return None
                self._ctx = self._new_context()
        ctx = self._ctx
        if ctx is None:
            self.stats.waiting_drops += 1
            return None
        try:
            frames = ctx.decode(av.Packet(access_unit))
        except (av.error.FFmpegError, ValueError):
            self._error()
            return None
        if not frames:
            if idr:
                self._waiting = False  # headers accepted; FFmpeg may hold the first picture (it should not)
            return None
        frame = frames[-1]
        if self._size is not None and (frame.width, frame.height) != self._size:
            self._error()
            return None
        self._waiting = False
        self.stats.pictures += 1
        image = frame.reformat(format="bgr24", interpolation=TO_BGR).to_ndarray()
        assert image.dtype == np.uint8
        return DecodedPicture(image.astype(np.uint8, copy=False), idr, stamp)

    def _new_context(self) -> av.VideoCodecContext:
        ctx = av.VideoCodecContext.create("h264", "r")
        ctx.thread_count = 1  # frame threads would hold pictures back by (threads - 1) frames
        ctx.options = {"err_detect": "explode"}  # report corrupt slices instead of concealing them
        ctx.open()
        return ctx

    def _reset(self) -> None:
        if self._ctx is not None:
            self.stats.resets += 1
        self._ctx = None

    def _error(self) -> None:
        self.stats.decode_errors += 1
        self._waiting = True
        self._reset()
