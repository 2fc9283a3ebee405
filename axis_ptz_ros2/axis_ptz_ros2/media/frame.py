"""The one frame type of the video path: a camera JPEG or an H.264 access unit, from its source (the MJPEG reader,
the transcoder, the camera's RTSP stream) through the H.264 stage and the pipeline to the node that publishes it."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

#: :attr:`EncodedFrame.codec` of a camera JPEG
JPEG: Final = "jpeg"
#: :attr:`EncodedFrame.codec` of an H.264 access unit
H264: Final = "h264"


@dataclass(frozen=True, slots=True)
class EncodedFrame:
    """One picture, encoded: a JPEG (``codec`` :data:`JPEG`) or one H.264 access unit in Annex B (:data:`H264`).

    ``keyframe``: an H.264 IDR (which then carries its SPS/PPS); every JPEG is one. ``pts``: a unique, increasing
    counter of its source (H.264: no B-frames, so decode order = presentation order). ``width``/``height``: the
    picture's size (0 where not read). ``capture_ns``: the capture stamp (UNIX ns; a JPEG's is its arrival on this
    host, an RTSP access unit's its RTP time on this host's clock, a transcoded one's its JPEG's) when known.
    ``grey``: a greyscale JPEG (one component).
    """

    data: bytes
    keyframe: bool
    pts: int
    width: int
    height: int
    capture_ns: int | None = None
    codec: str = H264
    grey: bool = False

    def __repr__(self) -> str:
        kind = ("IDR" if self.keyframe else "P") if self.codec == H264 else self.codec.upper()
        return (
            f"EncodedFrame({len(self.data)} bytes, {kind}, pts={self.pts}, "
            f"{self.width}x{self.height}, capture_ns={self.capture_ns})"
        )

    @property
    def stamp_ns(self) -> int:
        """The capture stamp, 0 where unknown (what a message header carries)."""
        return self.capture_ns or 0
