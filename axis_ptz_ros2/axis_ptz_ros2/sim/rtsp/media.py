"""What the simulated camera's RTSP server streams: the ``/axis-media/media.amp`` arguments, the SDP, the encoder.

VAPIX RTSP API arguments (vapix.md §5.6, h264.md "Axis cameras"): ``videocodec`` (only ``h264`` is encoded here),
``resolution`` (the persona's list, as on ``video.cgi``), ``fps`` (0 = the camera's top rate,
``Persona.frame_rate``; more is served at that rate), ``videokeyframeinterval`` (default 32), ``videozgopmode``
(``fixed``/``dynamic``), ``videobitratemode`` (``vbr``/``mbr``/``abr``/``cbr``) with ``videomaxbitrate`` (kbit/s; a
rate option without the mode is refused), ``h264profile``, ``adjustablelivestream``, ``camera``, ``compression``,
``audio``. A bad value is a :class:`MediaError` carrying the RTSP status the camera answers with.
"""

from __future__ import annotations

import base64
from dataclasses import dataclass
from typing import Final

from axis_ptz_ros2.media import annexb
from axis_ptz_ros2.media.h264_settings import H264Settings
from axis_ptz_ros2.media.limits import ENCODER_BITRATE_RANGE_KBPS, MAX_KEYFRAME_INTERVAL
from axis_ptz_ros2.sim.frames import MAX_COMPRESSION, MAX_FPS
from axis_ptz_ros2.sim.request_args import int_arg
from axis_ptz_ros2.sim.rtsp.rtp import CLOCK_RATE, PAYLOAD_TYPE
from axis_ptz_ros2.sim.view import CameraView

MEDIA_PATH: Final = "/axis-media/media.amp"
VIDEO_CODECS: Final = ("h264", "h265", "av1", "mpeg4", "jpeg")  #: what VAPIX names (vapix.md §5.6)
DEFAULT_KEYFRAME_INTERVAL: Final = 32  #: Axis's default (h264.md)
DEFAULT_BITRATE_KBPS: Final = 2000  #: used without videomaxbitrate (a guess: Axis's own default is scene-driven)
H264_PROFILES: Final = ("baseline", "main", "high")
BITRATE_MODES: Final = ("vbr", "mbr", "abr", "cbr")


class MediaError(Exception):
    """A request the camera refuses: ``status`` (RTSP code) and the reason."""

    def __init__(self, status: int, reason: str) -> None:
        super().__init__(reason)
        self.status = status


@dataclass(frozen=True, slots=True)
class MediaRequest:
    """Validated ``media.amp`` arguments."""

    width: int
    height: int
    fps: int
    keyframe_interval: int
    bitrate_kbps: int
    adjustable: bool

    def h264_settings(self) -> H264Settings:
        """The libx264 settings for this stream (veryfast up to 4CIF, ultrafast above: two shared cores); the
        encoder takes the size (``width``, ``height``) beside them."""
        preset = "veryfast" if self.width * self.height <= 704 * 576 else "ultrafast"
        return H264Settings(
            fps=self.fps,
            bitrate_kbps=self.bitrate_kbps,
            keyframe_interval=min(self.keyframe_interval, MAX_KEYFRAME_INTERVAL),
            preset=preset,
            profile="baseline",  # an Axis camera's (the request's h264profile is not honoured)
            refresh="idr",  # a fixed GOP: an IDR every videokeyframeinterval
        )


def parse_media_args(cam: CameraView, args: list[tuple[str, str]]) -> MediaRequest:
    """Validate ``media.amp`` arguments for ``cam``; raises :class:`MediaError` (400 or 415)."""
    a = {k.lower(): v for k, v in args}

    def integer(name: str, lo: int, hi: int, default: int) -> int:
        try:
            return int_arg(a, name, lo, hi, default)
        except ValueError as err:
            raise MediaError(400, str(err)) from err

    def choice(name: str, allowed: tuple[str, ...]) -> str | None:
        v = a.get(name)
        if v is not None and v.lower() not in allowed:
            raise MediaError(400, f"Invalid {name}: {v}")
        return v.lower() if v is not None else None

    codec = (choice("videocodec", VIDEO_CODECS) or "h264").lower()
    formats = cam.params.get("Properties.Image.Format", "").split(",")
    if codec not in formats or codec != "h264":
        raise MediaError(415, f"Unsupported video codec: {codec}")
    if a.get("camera", "1") != "1":
        raise MediaError(404, f"Camera {a['camera']} not available")
    try:
        w, h = cam.persona.parse_resolution(a.get("resolution", cam.params["Image.I0.Appearance.Resolution"]), False)
    except ValueError as err:
        raise MediaError(400, str(err)) from err
    rate = cam.persona.frame_rate  # the most pictures a second the camera makes
    fps = min(integer("fps", 0, MAX_FPS, 0) or rate, rate)
    kf = integer("videokeyframeinterval", 1, 1023, DEFAULT_KEYFRAME_INTERVAL)
    choice("videozgopmode", ("fixed", "dynamic"))
    choice("h264profile", H264_PROFILES)
    choice("videozprofile", ("classic", "storage", "low", "high", "higher", "extreme"))
    mode = choice("videobitratemode", BITRATE_MODES)
    integer("compression", 0, MAX_COMPRESSION, 30)
    integer("audio", 0, 1, 0)
    adjustable = integer("adjustablelivestream", 0, 1, 0) == 1
    rate_given = any(k in a for k in ("videomaxbitrate", "videobitrate", "videobitratepriority"))
    if rate_given and mode is None:
        raise MediaError(400, "videobitratemode is required with a bitrate option")
    low, high = ENCODER_BITRATE_RANGE_KBPS
    kbps = integer("videomaxbitrate", 0, high, 0)
    if kbps and kbps < low:
        raise MediaError(400, f"Invalid videomaxbitrate: {a['videomaxbitrate']}")
    return MediaRequest(w, h, fps, kf, kbps or DEFAULT_BITRATE_KBPS, adjustable)


def parameter_sets(request: MediaRequest) -> annexb.ParameterSets:
    """The SPS/PPS the session's encoder will use (libx264 is deterministic for one configuration)."""
    import numpy as np  # noqa: PLC0415 - only here

    from axis_ptz_ros2.media.encoder import H264Encoder  # noqa: PLC0415 - PyAV, on first use

    enc = H264Encoder(request.h264_settings(), request.width, request.height)
    au = enc.encode_bgr(np.zeros((request.height, request.width, 3), np.uint8)).data
    sps = pps = None
    for nal in annexb.split_nal_units(au):
        if nal[0] & 0x1F == annexb.NalType.SPS:
            sps = nal
        elif nal[0] & 0x1F == annexb.NalType.PPS:
            pps = nal
    if sps is None or pps is None:
        raise RuntimeError("libx264 gave an IDR without SPS/PPS")
    return annexb.ParameterSets(sps, pps)


def sdp(request: MediaRequest, params: annexb.ParameterSets, host: str, base: str, query: str, session_id: int) -> str:
    """The session description an Axis camera's DESCRIBE answers with (one H.264 video stream); the stream's
    control URL is ``<base>/stream=0?<query>`` (the arguments travel with SETUP, as on Axis cameras)."""
    q = f"?{query}" if query else ""
    sprop = ",".join(base64.b64encode(x).decode() for x in (params.sps, params.pps))
    profile_level_id = params.sps[1:4].hex().upper()
    lines = [
        "v=0",
        f"o=- {session_id} 1 IN IP4 {host}",
        "s=Session streamed with GStreamer",  # what an Axis camera's SDP says (h264.md)
        "i=rtsp-server",
        "t=0 0",
        "a=tool:GStreamer",
        "a=type:broadcast",
        "a=range:npt=now-",
        f"a=control:{base}{q}",
        f"m=video 0 RTP/AVP {PAYLOAD_TYPE}",
        "c=IN IP4 0.0.0.0",
        f"b=AS:{request.bitrate_kbps}",
        f"a=rtpmap:{PAYLOAD_TYPE} H264/{CLOCK_RATE}",
        f"a=fmtp:{PAYLOAD_TYPE} packetization-mode=1;profile-level-id={profile_level_id};sprop-parameter-sets={sprop}",
        f"a=control:{base}/stream=0{q}",
        f"a=framerate:{request.fps}.000000",
        "a=recvonly",
    ]
    return "\r\n".join(lines) + "\r\n"
