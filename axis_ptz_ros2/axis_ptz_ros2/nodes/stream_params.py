"""The stream node's parameters: one :class:`~axis_ptz_ros2.nodes.common.ParamSpec` table (names, defaults,
ranges, descriptions; the README's table and ``config/*.yaml`` are checked against it).

Live video parameters take their defaults from :class:`~axis_ptz_ros2.streaming.video_types.VideoSettings` (the
``h264_*`` ones from its :class:`~axis_ptz_ros2.media.h264_settings.H264Settings`) and the
reader's timings from :class:`~axis_ptz_ros2.streaming.reader.ReaderConfig`, field for field; ranges come from the
VAPIX models, the one table of H.264 bounds and defaults (:mod:`~axis_ptz_ros2.media.limits`) and
:mod:`~axis_ptz_ros2.streaming.limits` (the budget's, which the console's
API checks too).
"""

from __future__ import annotations

from typing import Any

from axis_ptz_ros2.media.limits import BITRATE_RANGE_KBPS, CODECS, KEYFRAME_RANGE, PRESETS, REPORTED_WAVE_RANGE
from axis_ptz_ros2.nodes.camera_info_service import PARAMS as CAMERA_INFO_PARAMS
from axis_ptz_ros2.nodes.common import CONNECTION_PARAMS, ParamSpec, field_spec
from axis_ptz_ros2.streaming import ReaderConfig
from axis_ptz_ros2.streaming.h264_policy import H264_BUDGET_FRACTION
from axis_ptz_ros2.streaming.limits import BUDGET_RANGE_KBPS
from axis_ptz_ros2.streaming.video_types import VideoSettings
from axis_ptz_ros2.vapix.models import COMPRESSION_RANGE, FPS_RANGE


def _live(field: str, description: str, unit: str = "", **kw: Any) -> ParamSpec:
    """A live video parameter: fills ``VideoSettings.<field>``, its default from there."""
    return field_spec(VideoSettings, field, description, unit, **kw)


def _h264(field: str, description: str, unit: str = "", **kw: Any) -> ParamSpec:
    """A live H.264 parameter ``h264_<field>``: fills ``VideoSettings.h264.<field>``, its default from there."""
    return field_spec(VideoSettings, f"h264.{field}", description, unit, name=f"h264_{field}", **kw)


def _timing(name: str, description: str, low: float, high: float) -> ParamSpec:
    """A read-only timing of the reader [s]: the parameter ``name`` fills ``ReaderConfig.<name>_s``."""
    return field_spec(ReaderConfig, f"{name}_s", description, "s", name=name, float_range=(low, high), read_only=True)


PARAMS: tuple[ParamSpec, ...] = (
    # -- video (live): defaults from VideoSettings, ranges from the VAPIX models --
    _live("fps", "frames per second requested from the camera", "1/s", int_range=FPS_RANGE),
    _live(
        "resolution",
        "image size 'WIDTHxHEIGHT' (or a CIF name), from the camera's list (Properties.Image.Resolution); "
        "'' = the largest the camera lists (a camera's own H.264 passed through: the largest with 0.03 bit per "
        "pixel per picture at the bitrate in force, docs/weak-link.md)",
        "px",
    ),
    _live(
        "compression",
        "JPEG compression (0 = best quality, 100 = smallest)",
        int_range=COMPRESSION_RANGE,
    ),
    _live(
        "max_bitrate_kbps",
        "bandwidth budget: step compression, then fps, then resolution (keeping the requested shape) down to stay "
        "under it (0 = off); "
        "codec h264: caps the encoder's bitrate instead",
        "kbit/s",
        int_range=BUDGET_RANGE_KBPS,
    ),
    _live(
        "budget_max_compression",
        "highest compression the budget may choose before lowering fps",
        int_range=COMPRESSION_RANGE,
    ),
    _live(
        "budget_min_fps",
        "the budget lowers fps only down to this before lowering the resolution (then below it)",
        "1/s",
        int_range=FPS_RANGE,
    ),
    _live(
        "adapt_to_link",
        "follow the consumers' video/feedback: a budget from what arrives at them (see docs/weak-link.md)",
    ),
    _live(
        "link_release",
        "drop the feedback budget after this long without a report (held through shorter silences: link cuts)",
        "s",
        float_range=(2.0, 3600.0),
    ),
    _live(
        "codec",
        "'h264': image_raw/ffmpeg and image_raw/foxglove carry H.264: a camera that streams H.264 passes its own "
        "through (RTSP), others are asked for compression 0 and encoded here; the budget drives the bitrate "
        "instead of the MJPEG ladder",
        choices=CODECS,
    ),
    _h264(
        "bitrate_kbps",
        "H.264 bitrate; applies as is without feedback (the safe default), a lower budget (link or "
        "max_bitrate_kbps) lowers it",
        "kbit/s",
        int_range=BITRATE_RANGE_KBPS,
    ),
    _h264(
        "max_bitrate_kbps",
        "H.264 bitrate ceiling: consumers' feedback of a clear link (adapt_to_link) may raise the bitrate up to "
        f"this, at most {H264_BUDGET_FRACTION:g} × the link's budget; at or below h264_bitrate_kbps "
        "never above it",
        "kbit/s",
        int_range=BITRATE_RANGE_KBPS,
    ),
    _h264(
        "keyframe_interval",
        "frames per wave of x264's intra refresh when transcoding (IDRs then only on demand), or between a camera's "
        "own IDRs when passed through (at most fps, one second, applies)",
        "frames",
        int_range=KEYFRAME_RANGE,
    ),
    _h264(
        "reported_wave",
        "frames per wave of x264's intra refresh when transcoding while every H.264 subscriber reports its losses "
        "on video/feedback and none reported one for 30 s (0: off); more bits for the picture on a clean link, "
        "but each IDR's blur lasts longer (docs/weak-link.md)",
        "frames",
        int_range=REPORTED_WAVE_RANGE,
    ),
    _h264("preset", "libx264 preset (CPU against quality)", choices=PRESETS),
    ParamSpec(
        "zoom", 1.0, "zoom for camera_info until ptz/state is received", "VAPIX units", float_range=(1.0, 99999.0)
    ),
    ParamSpec(
        "lazy",
        True,
        "stream only while someone subscribes to image_raw/compressed, camera_info or (codec h264) the H.264 topics",
    ),
    # -- frames and model (read-only) --
    ParamSpec(
        "frame_id", "axis_ptz_optical_frame", "frame_id of images and camera_info (after frame_prefix)", read_only=True
    ),
    ParamSpec(
        "frame_prefix",
        "",
        "prefix of frame_id (e.g. 'robot1/'); set it to axis_ptz's frame_prefix so the images name the /tf frame",
        read_only=True,
    ),
    ParamSpec(
        "camera_model",
        "",
        "camera-model YAML ('' = chosen by the camera's reported model, else config/generic.yaml with the "
        "camera's own optics)",
        read_only=True,
    ),
    *CAMERA_INFO_PARAMS,  # camera_info_url, camera_name (read-only)
    # -- connection (read-only) --
    *CONNECTION_PARAMS,
    ParamSpec(
        "rtsp_port",
        554,
        "camera RTSP port (codec h264 from a camera that streams H.264)",
        int_range=(1, 65535),
        read_only=True,
    ),
    _timing("read_timeout", "socket read timeout of the stream", 0.05, 60.0),
    # -- self-healing (read-only) --
    _timing(
        "stall_timeout", "reconnect when the newest frame is older than this (at least 3 frame periods)", 0.05, 60.0
    ),
    _timing("backoff_initial", "first reconnect delay", 0.001, 60.0),
    _timing("backoff_max", "reconnect delay cap, counted from the start of the failed attempt", 0.001, 600.0),
    _timing("auth_retry", "retry delay after a refused login (401/403)", 0.01, 3600.0),
)
SPECS = {s.name: s for s in PARAMS}
