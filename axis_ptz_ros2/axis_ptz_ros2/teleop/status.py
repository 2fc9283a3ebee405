"""What the operator is shown in words (ROS-free): the keyboard teleop's status line, and the video wording it shares
with the web console (:func:`video_text`: the console's video line and its answers to video commands).

Messages are read through small protocols (attribute names of ``PtzState`` / ``VideoParams``), so tests use plain
objects.
"""

from __future__ import annotations

import math
from typing import Protocol


class PtzLike(Protocol):
    """The fields of ``axis_ptz_interfaces/PtzState`` the status line shows."""

    pan: float
    tilt: float
    zoom: float
    magnification: float
    hfov: float
    moving: bool


class VideoLike(Protocol):
    """The fields of ``axis_ptz_interfaces/VideoParams`` :func:`video_text` words."""

    fps: int
    resolution: str
    compression: int
    codec: str
    h264_bitrate_kbps: int
    h264_max_bitrate_kbps: int


def video_text(p: VideoLike) -> str:
    """The parameters a stream streams with, in words: the JPEG compression, or in H.264 mode the bitrates."""
    if p.codec != "h264":
        quality = f"compression {p.compression}"
    elif p.h264_max_bitrate_kbps > p.h264_bitrate_kbps:
        quality = f"H.264 {p.h264_bitrate_kbps} kbit/s (up to {p.h264_max_bitrate_kbps} with feedback)"
    else:
        quality = f"H.264 {p.h264_bitrate_kbps} kbit/s"
    return f"{p.resolution} at {p.fps} fps, {quality}"


def _deg(rad: float) -> float:
    """Degrees for display, without a "-0.00"."""
    d = round(math.degrees(rad), 2)
    return d + 0.0 if d != 0.0 else 0.0


def ptz_text(s: PtzLike | None) -> str:
    """``pan … deg  tilt … deg  zoom … (…x, hfov … deg)`` (+ ``moving``), or that no state came yet."""
    if s is None:
        return "PTZ: waiting for ptz/state"
    return (
        f"pan {_deg(s.pan):+7.2f} deg  tilt {_deg(s.tilt):+6.2f} deg  "
        f"zoom {s.zoom:5.0f} ({s.magnification:.1f}x, hfov {math.degrees(s.hfov):.1f} deg)"
        + ("  moving" if s.moving else "")
    )


def status_line(ptz: PtzLike | None, video: VideoLike | None, step: int) -> str:
    """The keyboard teleop's status line: ``pan … tilt … zoom … | video: 704x576 at 15 fps, compression 30 |
    step 1 | ? help`` (``video: waiting`` before the stream node's first ``video/params``)."""
    v = "video: waiting" if video is None else f"video: {video_text(video)}"
    return f"{ptz_text(ptz)} | {v} | step {step} | ? help"
