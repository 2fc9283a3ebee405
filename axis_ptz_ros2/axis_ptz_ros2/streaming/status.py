"""What the stream node says about itself: reader events as (throttled) log lines, the diagnostics status
(with the H.264 side's values and the line that says where its H.264 comes from). ROS-free (levels are
``diagnostic_msgs/DiagnosticStatus`` values as integers).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from axis_ptz_ros2.media.h264_settings import H264Settings
from axis_ptz_ros2.streaming.h264 import StageStats
from axis_ptz_ros2.streaming.meter import Rate
from axis_ptz_ros2.streaming.reader import ReaderStats, StreamState
from axis_ptz_ros2.streaming.rtsp_source import RtspSourceStats
from axis_ptz_ros2.streaming.video_types import VideoState
from axis_ptz_ros2.vapix.models import VideoParams

OK, WARN, ERROR, STALE = 0, 1, 2, 3  # DiagnosticStatus levels

_STATE_LEVEL = {
    StreamState.STREAMING: OK,
    StreamState.IDLE_LAZY: OK,
    StreamState.CONNECTING: OK,
    StreamState.STOPPED: STALE,
    StreamState.RECONNECTING: WARN,
    StreamState.AUTH_FAILED: ERROR,
    StreamState.INVALID_PARAMS: ERROR,
}


@dataclass(frozen=True, slots=True)
class LogLine:
    """A log line: severity ("info", "warn", "error"), throttling key and period (0 = never throttled)."""

    level: str
    text: str
    key: str = ""
    period_s: float = 0.0


class LogThrottle:
    """At most one line per key and period, so an absent camera does not flood the log (thread-safe enough:
    a race lets one extra line through)."""

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        """No key has been logged yet."""
        self._clock = clock
        self._last: dict[str, float] = {}

    def allow(self, line: LogLine) -> bool:
        """Whether to log ``line`` now (and remember that it was)."""
        if not line.key or line.period_s <= 0:
            return True
        now = self._clock()
        if now - self._last.get(line.key, -1e18) < line.period_s:
            return False
        self._last[line.key] = now
        return True

    def forget(self, key: str) -> None:
        """Log the next line of ``key`` at once."""
        self._last.pop(key, None)


def reader_event_line(state: StreamState, message: str, params: VideoParams, auth_retry_s: float) -> LogLine | None:
    """The log line for a reader state change or error (None = nothing to say)."""
    if state is StreamState.AUTH_FAILED:
        return LogLine(
            "error",
            f"camera refused the login: {message} (check password_file / AXIS_USERNAME / AXIS_PASSWORD; "
            f"retrying every {auth_retry_s:g} s)",
            "auth",
            30.0,
        )
    if state is StreamState.INVALID_PARAMS:
        return LogLine("error", f"camera cannot stream these parameters: {message}", "invalid", 10.0)
    if state is StreamState.RECONNECTING:
        return LogLine("warn", f"stream lost, reconnecting: {message}", "reconnect", 5.0)
    if state is StreamState.STREAMING:
        return LogLine("info", f"streaming {params.resolution} @ {params.fps} fps")
    return None


def diagnostic_status(
    s: ReaderStats, rate: Rate, video: VideoState, extra: Mapping[str, Any]
) -> tuple[int, str, dict[str, Any]]:
    """(level, message, values) of the stream's diagnostics status; ``extra`` is appended to the values."""
    vp = s.params
    values: dict[str, Any] = {
        "state": s.state.value,
        "fps": rate.fps,
        "kbit/s": rate.kbps,
        "frame age [s]": s.frame_age_s if s.frame_age_s is not None else float("nan"),
        "frames": s.frames,
        "drops": s.drops,
        "truncated": s.parser.dropped_truncated,
        "corrupt": s.parser.dropped_corrupt,
        "garbage bytes": s.parser.garbage_bytes,
        "resyncs": s.parser.resyncs,
        "reconnects": s.reconnects,
        "stalls": s.stalls,
        "auth failures": s.auth_failures,
        "requested": f"{vp.resolution} @ {vp.fps} fps, compression {vp.compression}",
        "max_bitrate_kbps": int(video.budget_kbps),
        "budget level": video.level,
        "link budget [kbit/s]": video.link_budget_kbps,
        "link state": video.link_state,
        "link queue delay [s]": video.link_queue_delay_s,
        "last error": s.last_error,
        **extra,
    }
    message = s.state.value
    if s.state is StreamState.AUTH_FAILED:
        message = "authentication failed: " + s.last_error
    elif s.state is StreamState.RECONNECTING and s.last_error:
        message = "reconnecting: " + s.last_error
    elif s.state is StreamState.INVALID_PARAMS:
        message = "invalid parameters: " + s.last_error
    return _STATE_LEVEL[s.state], message, values


def h264_mode_line(camera_streams_h264: bool) -> str:
    """What ``codec`` = ``h264`` does with this camera (logged once, when first known)."""
    if camera_streams_h264:
        return "codec h264: the camera streams H.264: its own stream (RTSP) is passed through, not re-encoded"
    return "codec h264: the camera does not stream H.264: its MJPEG (compression 0) is transcoded to H.264 on this host"


def wave_line(h264: H264Settings) -> str:
    """The encoder's intra-refresh wave changed (logged at info): how long, and why. The short wave is named as
    "one second of frames": the stage runs the encoder at the rate the camera really makes, not ``h264.fps``."""
    if h264.long_wave:
        return (
            f"H.264 intra-refresh wave {h264.reported_wave} frames (h264_reported_wave): every H.264 "
            "subscriber reports its losses on video/feedback (each asks for an IDR) and none lost any lately"
        )
    return (
        "H.264 intra-refresh wave at most one second of frames: an H.264 subscriber does not report its losses, "
        "or one lost access units lately"
    )


def h264_diagnostic_values(
    encoding: bool,
    bitrate_kbps: int,
    stage: StageStats,
    rtsp: RtspSourceStats,
    camera_streams_h264: bool | None,
    start_kbps: int = 0,
    ceiling_kbps: int = 0,
    wave_frames: int = 0,
) -> dict[str, Any]:
    """The H.264 side's diagnostics values (``camera_streams_h264``: None until the camera was asked;
    ``start_kbps``/``ceiling_kbps``: ``h264_bitrate_kbps``/``h264_max_bitrate_kbps``, between which the link moves
    the target; ``wave_frames``: the keyframe interval the encoder or the camera's stream has now)."""
    return {
        "h264 encoding": encoding,
        "h264 bitrate target [kbit/s]": bitrate_kbps,
        "h264 bitrate start [kbit/s]": start_kbps,
        "h264 bitrate ceiling [kbit/s]": ceiling_kbps,
        "h264 access units": stage.frames,
        "h264 IDRs": stage.idrs,
        "h264 IDRs on demand": stage.idr_requests,
        "h264 keyframe interval [frames]": wave_frames,
        "h264 dropped inputs": stage.bad_inputs,
        "h264 source": {None: "?", True: "camera (RTSP)", False: "transcoded"}[camera_streams_h264],
        "rtsp access units": rtsp.access_units,
        "rtsp reconnects": rtsp.reconnects,
        "rtsp Renew-Stream": rtsp.renews,
        # the camera's wall clock behind (+) / ahead (-) of this host's, from RTCP sender reports ("" before one);
        # stamps are on this host's clock either way (streaming/clock_sync.py)
        "rtsp camera clock offset [s]": ""
        if rtsp.camera_clock_offset_s is None
        else round(rtsp.camera_clock_offset_s, 3),
    }
