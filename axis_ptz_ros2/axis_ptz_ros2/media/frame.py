"""The one encoded-frame type that flows from a source (transcoder, RTSP) to the node that publishes it."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class EncodedFrame:
    """One H.264 access unit in Annex B, exactly one picture.

    ``keyframe`` is True for an IDR (which then carries its SPS/PPS); ``pts`` is a unique, increasing counter
    (no B-frames, so decode order = presentation order); ``capture_ns`` is the camera's capture time (UNIX ns)
    when known.
    """

    data: bytes
    keyframe: bool
    pts: int
    width: int
    height: int
    capture_ns: int | None = None
    codec: str = "h264"

    def __repr__(self) -> str:
        return (
            f"EncodedFrame({len(self.data)} bytes, {'IDR' if self.keyframe else 'P'}, pts={self.pts}, "
            f"{self.width}x{self.height}, capture_ns={self.capture_ns})"
        )
