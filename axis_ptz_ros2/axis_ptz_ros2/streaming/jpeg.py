"""Cheap JPEG header readers: the frame size and component count from SOF without decoding, and COM segments.
ROS-free."""

from __future__ import annotations

from collections.abc import Iterator

_SOF_MARKERS = frozenset({0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF})
_STANDALONE = frozenset({0x01, *range(0xD0, 0xD8)})


def _segments(data: bytes | bytearray | memoryview) -> Iterator[tuple[int, int, int]]:
    """``(marker, payload_start, payload_end)`` of the header segments up to SOS (no entropy data)."""
    n = len(data)
    if n < 4 or data[0] != 0xFF or data[1] != 0xD8:
        return
    i = 2
    while i + 4 <= n:
        if data[i] != 0xFF:
            return
        marker = data[i + 1]
        if marker == 0xFF:  # fill byte
            i += 1
            continue
        if marker in _STANDALONE:
            i += 2
            continue
        if marker in (0xD9, 0xDA):  # EOI / SOS: the header is over
            return
        length = (data[i + 2] << 8) | data[i + 3]
        if length < 2 or i + 2 + length > n:
            return
        yield marker, i + 4, i + 2 + length
        i += 2 + length


def jpeg_sof(data: bytes | bytearray | memoryview) -> tuple[int, int, int] | None:
    """``(width, height, components)`` from the SOF segment in one walk of the header (components 1: greyscale,
    3: colour); None if there is no usable SOF."""
    for marker, start, end in _segments(data):
        if marker in _SOF_MARKERS and end - start >= 6:
            height = (data[start + 1] << 8) | data[start + 2]
            width = (data[start + 3] << 8) | data[start + 4]
            return (width, height, int(data[start + 5])) if width and height else None
    return None


def jpeg_size(data: bytes | bytearray | memoryview) -> tuple[int, int] | None:
    """``(width, height)`` from the SOF segment, reading only the header; None if there is none."""
    sof = jpeg_sof(data)
    return None if sof is None else (sof[0], sof[1])


def jpeg_components(data: bytes | bytearray | memoryview) -> int | None:
    """The number of colour components in the SOF segment (1: greyscale, 3: YCbCr/colour); None if none."""
    sof = jpeg_sof(data)
    return None if sof is None else sof[2]


def jpeg_comments(data: bytes | bytearray | memoryview) -> list[bytes]:
    """Payloads of the COM (``FF FE``) segments before the scan."""
    return [bytes(data[start:end]) for marker, start, end in _segments(data) if marker == 0xFE]
