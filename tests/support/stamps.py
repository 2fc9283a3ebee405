"""The simulated camera's frame stamp, read back from a JPEG: test and bench tooling (the driver never needs it)."""

from __future__ import annotations

from axis_ptz_ros2.streaming.jpeg import jpeg_comments


def sim_stamp(data: bytes | bytearray | memoryview) -> tuple[int, int] | None:
    """``(seq, t_ns)`` from the simulated camera's ``axsim seq=<n> t=<time_ns at send>`` comment."""
    for text in jpeg_comments(data):
        if not text.startswith(b"axsim"):
            continue
        fields = dict(tok.split(b"=", 1) for tok in text.split() if b"=" in tok)
        try:
            return int(fields[b"seq"]), int(fields[b"t"])
        except (KeyError, ValueError):
            return None
    return None
