"""The one table of H.264 bounds and defaults (ROS-free, PyAV-free, imports nothing).

Everything that checks, describes or fills an H.264 setting reads it from here: the stream node's parameter
descriptors and the README's generated table (``nodes/stream_params.py``), the codec check
(:func:`~axis_ptz_ros2.streaming.h264_policy.check_h264`), the one settings
type from the request to the encoder (:class:`~axis_ptz_ros2.media.h264_settings.H264Settings`, which enforces the
encoder's bounds), the RTSP request to a camera (:func:`~axis_ptz_ros2.streaming.rtsp_source.media_request`), the
simulated camera's encoder and the teleop keys' bitrate steps. PyAV-free so that settings can be checked, and the
stream node can start, on a machine without PyAV.

Two bitrate ranges, each defined once: what the encoder (and a camera's ``videomaxbitrate``, VAPIX) takes,
:data:`ENCODER_BITRATE_RANGE_KBPS`, and the narrower one the stream node's ``h264_bitrate_kbps`` /
``h264_max_bitrate_kbps`` may be set to, :data:`BITRATE_RANGE_KBPS` (inside the first: the stage never hands the
encoder or the camera a bitrate they refuse).
"""

from __future__ import annotations

from typing import Final

#: ``codec``: the stream node's video codecs
CODECS: Final = ("mjpeg", "h264")
#: libx264 presets the encoder takes (``h264_preset``)
PRESETS: Final = ("ultrafast", "superfast", "veryfast", "faster", "fast", "medium")
#: H.264 profiles the encoder makes: ``baseline`` (x264's Constrained Baseline: CAVLC, 4x4 transform) and ``high``
#: (CABAC, 8x8 transform; still no B-frames, so no reordering)
PROFILES: Final = ("baseline", "high")
#: how a decoder gets a clean picture again without asking: ``idr``: an IDR every keyframe interval; ``intra``:
#: x264's periodic intra refresh (a column of intra blocks sweeps the picture once per keyframe interval, no IDR
#: after the first: IDRs only on request)
REFRESH_MODES: Final = ("idr", "intra")

#: kbit/s: what the encoder takes, and what a camera's ``videomaxbitrate`` may be (VAPIX: 50-50000)
ENCODER_BITRATE_RANGE_KBPS: Final = (50, 50_000)
#: kbit/s: ``h264_bitrate_kbps`` and ``h264_max_bitrate_kbps`` (the parameters'; the budgets never go under its floor)
BITRATE_RANGE_KBPS: Final = (100, 20_000)
MAX_KEYFRAME_INTERVAL: Final = 600
#: frames: ``h264_keyframe_interval`` (at most one second of frames applies)
KEYFRAME_RANGE: Final = (1, MAX_KEYFRAME_INTERVAL)
#: frames: ``h264_reported_wave``, the intra-refresh wave while every viewer reports its losses (0: off)
REPORTED_WAVE_RANGE: Final = (0, MAX_KEYFRAME_INTERVAL)
MAX_DIMENSION: Final = 4096
#: pictures/s the encoder runs at
ENCODER_FPS_RANGE: Final = (1, 120)
#: libx264 threads (1: one slice per picture, lowest CPU; more: sliced threads, lower latency at 1080p)
THREADS_RANGE: Final = (1, 16)

# -- defaults: the stream node's parameters and H264Settings' --
#: kbit/s: ``h264_bitrate_kbps``, the bitrate without feedback (a budget lowers it)
DEFAULT_BITRATE_KBPS: Final = 1000
#: kbit/s: ``h264_max_bitrate_kbps``, the most a clear link may raise it to (at or below ``h264_bitrate_kbps``: never
#: above it). On the thesis's link (2 Mbit/s + 2 %) 1500 held 25 fps with no access unit lost, 2000 ended in a
#: retransmission collapse (docs/weak-link.md, "The ceiling")
DEFAULT_MAX_BITRATE_KBPS: Final = 1500
#: frames: ``h264_keyframe_interval``, per intra-refresh wave (between IDRs with refresh ``idr``)
DEFAULT_KEYFRAME_INTERVAL: Final = 30
#: pictures/s the encoder runs at until told otherwise (the stream node's ``fps``; the stage runs it at the rate in
#: effect, measured at the camera)
DEFAULT_FPS: Final = 15
#: ``h264_preset`` (why superfast: docs/nodes.md, "H.264 encoder settings")
DEFAULT_PRESET: Final = "superfast"
#: the profile the stream node encodes (every decoder a viewer uses here decodes High: docs/nodes.md)
DEFAULT_PROFILE: Final = "high"
#: the stream node's refresh: intra refresh, IDRs only on demand (issue 39)
DEFAULT_REFRESH: Final = "intra"

#: s: the VBV buffer in seconds of the bitrate. bitrate/10 (the issue's prototype) starved every IDR and the
#: frames after it (PSNR 5th percentile 33.4 dB at 1000 kbit/s, 837 kbit/s used, against the simulated camera's
#: still view before noise); 0.15 s: 34.8 dB, 871 kbit/s, largest IDR 15 kB. A live step down spends what is
#: left of the old rate's buffer first (~8 frames from 2000 to 300 kbit/s).
VBV_BUFFER_S: Final = 0.15
#: a VBV buffer asked for live that differs from the open one by less than this fraction is not worth a re-open
VBV_REOPEN_SLACK: Final = 0.2
#: kbit: the smallest VBV buffer the encoder is given (0 asks for its default, :data:`VBV_BUFFER_S` of the bitrate)
MIN_VBV_KBIT: Final = 1
