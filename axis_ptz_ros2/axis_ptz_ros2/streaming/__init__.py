"""ROS-free machinery of the MJPEG stream node, one concern per module.

* :mod:`.jpeg` — cheap JPEG header readers (:func:`jpeg_size`, :func:`jpeg_comments`).
* :mod:`.meter` — :class:`Backoff` (capped exponential) and :class:`BitrateMeter` (frames/s, kbit/s).
* :mod:`.reader` — :class:`StreamReader`, the one justified thread (open, read, reconnect, watchdog).
* :mod:`.budget` — :class:`BandwidthController`, keeps the bitrate under a budget.
* :mod:`.feedback` — :class:`~.feedback.LinkAdapter`, a budget that follows what the consumers receive.
* :mod:`.controller` — :class:`~.controller.VideoController`, the one owner of the video parameters in effect
  (request, budget, link adaptation, the camera's sizes); :mod:`.h264_policy` turns its budgets into the H.264
  encoder's bitrate and VBV buffer.
* :mod:`.discovery` — :class:`~.discovery.CameraDiscovery`: what the camera is (once, with back-off), its stream
  (the reader's opener, with a TCP probe while the camera is unreachable).
* :mod:`.status` — reader events as throttled log lines, the diagnostics status.

Nothing here imports ``rclpy`` or ROS messages.
"""

from __future__ import annotations

from axis_ptz_ros2.streaming.budget import (
    AXIS214_PAL_RESOLUTIONS,
    BandwidthController,
    BudgetConfig,
    compression_size_factor,
)
from axis_ptz_ros2.streaming.jpeg import jpeg_comments, jpeg_size
from axis_ptz_ros2.streaming.meter import Backoff, BitrateMeter, Rate
from axis_ptz_ros2.streaming.reader import (
    FrameSource,
    ReaderConfig,
    ReaderStats,
    StreamOpener,
    StreamReader,
    StreamState,
)

__all__ = [
    "AXIS214_PAL_RESOLUTIONS",
    "Backoff",
    "BandwidthController",
    "BitrateMeter",
    "BudgetConfig",
    "FrameSource",
    "Rate",
    "ReaderConfig",
    "ReaderStats",
    "StreamOpener",
    "StreamReader",
    "StreamState",
    "compression_size_factor",
    "jpeg_comments",
    "jpeg_size",
]
