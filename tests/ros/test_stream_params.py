"""The stream node's parameter table is the one source of its configuration: the ROS-free config classes are
built from it (frozen snapshots), their defaults are the parameters' defaults, the ranges the VAPIX models'."""

from __future__ import annotations

import dataclasses

import pytest

pytest.importorskip("rclpy")

from axis_ptz_ros2.media.h264_settings import H264Settings  # noqa: E402
from axis_ptz_ros2.nodes.common import snapshot  # noqa: E402
from axis_ptz_ros2.nodes.stream_node import PARAMS  # noqa: E402
from axis_ptz_ros2.streaming import ReaderConfig  # noqa: E402
from axis_ptz_ros2.streaming.video_types import VideoSettings  # noqa: E402
from axis_ptz_ros2.vapix.models import COMPRESSION_RANGE, FPS_RANGE  # noqa: E402

pytestmark = pytest.mark.ros

DEFAULTS = {s.name: s.default for s in PARAMS}


def test_defaults_snapshot_to_the_config_classes_defaults():
    assert snapshot(VideoSettings, PARAMS, DEFAULTS) == VideoSettings()
    reader = snapshot(ReaderConfig, PARAMS, DEFAULTS)
    assert reader == ReaderConfig()
    with pytest.raises(dataclasses.FrozenInstanceError):
        reader.stall_timeout_s = 2.0  # type: ignore[misc]


def test_every_live_video_field_is_a_parameter_and_values_land_in_their_fields():
    filled = {s.field for s in PARAMS if s.config is VideoSettings}
    assert {f.split(".")[0] for f in filled} == {f.name for f in dataclasses.fields(VideoSettings)}
    # the h264_* parameters fill the one H.264 settings type the request carries (VideoSettings.h264)
    h264 = {s.name: s.field for s in PARAMS if s.field.startswith("h264.")}
    assert h264 == {
        f"h264_{n}": f"h264.{n}"
        for n in ("bitrate_kbps", "max_bitrate_kbps", "keyframe_interval", "reported_wave", "preset")
    }
    values = {**DEFAULTS, "fps": 7, "backoff_max": 0.7, "read_timeout": 3.0, "link_release": 9.0}
    values |= {
        "h264_bitrate_kbps": 700,
        "h264_max_bitrate_kbps": 900,
        "h264_keyframe_interval": 12,
        "h264_reported_wave": 75,
        "h264_preset": "fast",
    }
    want = H264Settings(bitrate_kbps=700, max_bitrate_kbps=900, keyframe_interval=12, reported_wave=75, preset="fast")
    assert snapshot(VideoSettings, PARAMS, values) == VideoSettings(fps=7, link_release=9.0, h264=want)
    assert snapshot(ReaderConfig, PARAMS, values) == ReaderConfig(backoff_max_s=0.7, read_timeout_s=3.0)


def test_ranges_come_from_the_vapix_models():
    specs = {s.name: s for s in PARAMS}
    assert specs["fps"].int_range == specs["budget_min_fps"].int_range == FPS_RANGE
    assert specs["compression"].int_range == specs["budget_max_compression"].int_range == COMPRESSION_RANGE
