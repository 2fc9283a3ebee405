"""What the stream node asks of the camera, from its settings. ROS-free.

The video controller (:mod:`.controller`) owns what is in effect; this module is the pure part of it that turns what
is asked for (:class:`~.video_types.VideoSettings`) into a request (:class:`~axis_ptz_ros2.vapix.models.VideoParams`):

* resolution ``""`` = the largest size the camera lists (:data:`AUTO_PLACEHOLDER` while it cannot list them);
* in ``h264`` mode (when it can be produced here) the camera is asked for compression 0, the encoder's best input;
  the MJPEG stream that runs beside it (:mod:`.mjpeg_share`) is asked for the compression asked for;
* a ``video/set_params`` request's fields, with their "leave as it is" values (:func:`requested_changes`).
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import replace
from typing import Final

from axis_ptz_ros2.streaming.video_types import VideoSettings
from axis_ptz_ros2.vapix.models import Resolution, VideoParams

#: resolution "" while the camera cannot list its sizes (discovery retries)
AUTO_PLACEHOLDER: Final = Resolution(704, 576)
#: the fields of :class:`VideoSettings` that make up the request and the budget (not the link adaptation)
VIDEO_FIELDS: Final = frozenset(
    {"fps", "resolution", "compression", "max_bitrate_kbps", "budget_max_compression", "budget_min_fps", "codec"}
)
#: the fields of :class:`VideoSettings` that tune the link adaptation
LINK_FIELDS: Final = frozenset({"adapt_to_link", "link_release"})


def largest(resolutions: Collection[Resolution]) -> Resolution:
    """The size with the most pixels (the wider one of two with as many)."""
    return max(resolutions, key=lambda r: (r.width * r.height, r.width))


def camera_request(
    settings: VideoSettings, resolutions: Collection[Resolution] | None, h264: bool, camera: int = 1
) -> VideoParams:
    """The request (not validated) for ``settings``; ``resolutions`` = the camera's own list once learned (None
    before), ``h264`` = whether H.264 is in effect (compression 0 then). Raises InvalidArgument for a resolution that
    cannot be parsed."""
    text = str(settings.resolution)
    auto = largest(resolutions) if resolutions else AUTO_PLACEHOLDER
    res = Resolution.parse(text) if text.strip() else auto
    compression = 0 if h264 else int(settings.compression)  # the encoder's best input
    return VideoParams(res, int(settings.fps), compression, camera=camera)


def share_request(settings: VideoSettings, resolutions: Collection[Resolution] | None, camera: int = 1) -> VideoParams:
    """The MJPEG stream's request in h264 mode: the size and rate asked for, at the compression asked for."""
    return replace(camera_request(settings, resolutions, True, camera), compression=int(settings.compression))


def requested_changes(
    fps: int, resolution: str, compression: int, h264_bitrate_kbps: int = 0, h264_max_bitrate_kbps: int = 0
) -> dict[str, int | str]:
    """The live parameters a ``video/set_params`` request changes: ``fps`` 0, ``resolution`` '',
    ``compression`` -1 and the H.264 bitrates 0 leave theirs as they are."""
    changes: dict[str, int | str] = {}
    if fps != 0:
        changes["fps"] = int(fps)
    if resolution:
        changes["resolution"] = str(resolution)
    if compression != -1:
        changes["compression"] = int(compression)
    if h264_bitrate_kbps != 0:
        changes["h264_bitrate_kbps"] = int(h264_bitrate_kbps)
    if h264_max_bitrate_kbps != 0:
        changes["h264_max_bitrate_kbps"] = int(h264_max_bitrate_kbps)
    return changes
