"""Ranges of the stream node's video values that more than one layer checks (ROS-free, imports nothing).

The stream node's parameter table (``nodes/stream_params.py``) and the console's API table (``web/api.py``) both
take them from here. The camera's own ranges (fps, compression) are the VAPIX models'
(:data:`~axis_ptz_ros2.vapix.models.FPS_RANGE`, :data:`~axis_ptz_ros2.vapix.models.COMPRESSION_RANGE`).
"""

from __future__ import annotations

from typing import Final

#: kbit/s: the hand-set bandwidth budget ``max_bitrate_kbps`` (0 = off)
BUDGET_RANGE_KBPS: Final = (0, 1_000_000)
