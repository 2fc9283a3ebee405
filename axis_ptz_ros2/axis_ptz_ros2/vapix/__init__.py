"""ROS-free, typed VAPIX client for Axis PTZ cameras (reference ``vapix.md`` §§1-6, 11, 12).

Modules: :mod:`.errors` (exception tree, status mapping), :mod:`.models` (frozen values and
lenient reply parsers), :mod:`.requests` (one dataclass per PTZ call), :mod:`.mjpeg` (incremental
multipart parser), :mod:`.auth` (Digest/Basic negotiation), :mod:`.client` (``VapixClient``: PTZ and video, on
:mod:`.device` (parameters, resolutions, device info) on :mod:`.transport` (connection, authentication, capped
replies)), :mod:`.mjpeg_stream` (``MjpegStream``), :mod:`.camera_config` (``CameraConfig``), :mod:`.replies`
(request paths, ``Error:`` bodies).
Nothing here imports ``rclpy`` or ROS messages.
"""

from axis_ptz_ros2.vapix.auth import AuthCounters, AuthMode, AuthScheme, NegotiatingAuth
from axis_ptz_ros2.vapix.camera_config import CameraConfig
from axis_ptz_ros2.vapix.client import VapixClient
from axis_ptz_ros2.vapix.errors import (
    AuthError,
    AxisPtzError,
    CameraTimeout,
    CameraUnreachable,
    CommandRejected,
    HttpStatusError,
    InvalidArgument,
    ResponseParseError,
)
from axis_ptz_ros2.vapix.mjpeg import MjpegParser, MjpegStats, boundary_from_content_type
from axis_ptz_ros2.vapix.mjpeg_stream import MjpegStream
from axis_ptz_ros2.vapix.models import DeviceInfo, Preset, PtzLimits, PtzPosition, Resolution, VideoParams
from axis_ptz_ros2.vapix.requests import (
    AbsoluteMove,
    AreaZoom,
    Center,
    ContinuousMove,
    GotoPreset,
    Move,
    MoveDirection,
    PtzQuery,
    PtzRequest,
    RelativeMove,
    RemovePreset,
    SetPreset,
    SetSpeed,
)

__all__ = [
    "AbsoluteMove",
    "AreaZoom",
    "AuthCounters",
    "AuthError",
    "AuthMode",
    "AuthScheme",
    "AxisPtzError",
    "CameraConfig",
    "CameraTimeout",
    "CameraUnreachable",
    "Center",
    "CommandRejected",
    "ContinuousMove",
    "DeviceInfo",
    "GotoPreset",
    "HttpStatusError",
    "InvalidArgument",
    "MjpegParser",
    "MjpegStats",
    "MjpegStream",
    "Move",
    "MoveDirection",
    "NegotiatingAuth",
    "Preset",
    "PtzLimits",
    "PtzPosition",
    "PtzQuery",
    "PtzRequest",
    "RelativeMove",
    "RemovePreset",
    "Resolution",
    "ResponseParseError",
    "SetPreset",
    "SetSpeed",
    "VapixClient",
    "VideoParams",
    "boundary_from_content_type",
]
