"""Errors of the media layer (ROS-free).

::

    MediaError
     ├── BitstreamError      malformed Annex B / NAL unit / SPS / SEI / sprop-parameter-sets input
     ├── EncoderError        invalid encoder parameters, or libx264 refused a frame
     ├── TranscodeError      a JPEG that does not decode
     └── DecoderError        invalid decoder use (bad input is counted, not raised)
"""

from __future__ import annotations


class MediaError(Exception):
    """Base of every error the media layer raises on purpose."""


class BitstreamError(MediaError, ValueError):
    """Bytes that are not what the H.264 syntax (ITU-T H.264 §7, Annex B) allows."""


class EncoderError(MediaError, ValueError):
    """An encoder parameter out of range, or a frame the encoder cannot take."""


class TranscodeError(MediaError, ValueError):
    """A JPEG that cannot be decoded (the encoder is left as it was)."""


class DecoderError(MediaError, ValueError):
    """A decoder used wrongly (corrupt input is counted and dropped, never raised)."""
