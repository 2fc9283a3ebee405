"""The stream node's ROS-free parts that are not the controller's: the camera-model file a parameter names, and
what the node says about its H.264 side (``streaming/discovery.py``, ``streaming/status.py``)."""

from __future__ import annotations

import pytest

from axis_ptz_ros2.config import default_config_path
from axis_ptz_ros2.streaming.discovery import camera_model_path
from axis_ptz_ros2.streaming.h264 import StageStats
from axis_ptz_ros2.streaming.rtsp_source import RtspSourceStats
from axis_ptz_ros2.streaming.status import h264_diagnostic_values, h264_mode_line

pytestmark = pytest.mark.unit


def test_camera_model_path_prefers_the_given_file_then_the_packaged_one(tmp_path):
    assert camera_model_path("") is None  # learn it from the camera
    own = tmp_path / "axis214.yaml"
    own.write_text("x: 1\n")
    assert camera_model_path(str(own)) == str(own)  # the file given wins over the packaged one of that name
    packaged = default_config_path("axis214.yaml")
    assert packaged.exists()
    assert camera_model_path(str(tmp_path / "elsewhere" / "axis214.yaml")) == str(packaged)
    missing = tmp_path / "no_such_model.yaml"
    assert camera_model_path(str(missing)) == str(missing)  # loading it then says what is missing


def test_h264_diagnostic_values_name_the_source():
    stage = StageStats(frames=7, idrs=2, idr_requests=1, bad_inputs=3)
    rtsp = RtspSourceStats(access_units=5, reconnects=1, renews=4)
    values = h264_diagnostic_values(True, 800, stage, rtsp, None)
    assert values["h264 source"] == "?"
    assert (values["h264 access units"], values["h264 IDRs"], values["h264 dropped inputs"]) == (7, 2, 3)
    assert (values["rtsp access units"], values["rtsp Renew-Stream"]) == (5, 4)
    assert values["rtsp camera clock offset [s]"] == ""  # no sender report yet
    rtsp.camera_clock_offset_s = 30.0123456
    assert h264_diagnostic_values(True, 800, stage, rtsp, None)["rtsp camera clock offset [s]"] == 30.012
    assert values["h264 bitrate target [kbit/s]"] == 800
    limits = h264_diagnostic_values(True, 800, stage, rtsp, None, start_kbps=1000, ceiling_kbps=1500)
    assert (limits["h264 bitrate start [kbit/s]"], limits["h264 bitrate ceiling [kbit/s]"]) == (1000, 1500)
    assert h264_diagnostic_values(True, 800, stage, rtsp, True)["h264 source"] == "camera (RTSP)"
    assert h264_diagnostic_values(False, 800, stage, rtsp, False)["h264 source"] == "transcoded"


def test_h264_mode_line_says_pass_through_or_transcode():
    assert "passed through" in h264_mode_line(True)
    assert "transcoded" in h264_mode_line(False)
