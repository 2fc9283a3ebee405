"""The operator's status wording without ROS (axis_ptz_ros2.teleop.status): the keyboard teleop's status line and
the video wording the web console shares."""

from __future__ import annotations

import math
from types import SimpleNamespace

import pytest

from axis_ptz_ros2.teleop.status import ptz_text, status_line, video_text
from axis_ptz_ros2.web import view

pytestmark = pytest.mark.unit


def _video(**kw):
    fields = {"fps": 15, "resolution": "704x576", "compression": 30, "codec": "mjpeg", "h264_bitrate_kbps": 1000,
              "h264_max_bitrate_kbps": 1500}  # fmt: skip
    return SimpleNamespace(**{**fields, **kw})


def _ptz(**kw):
    fields = {"pan": math.radians(-11.0), "tilt": 0.0, "zoom": 321.0, "magnification": 1.4,
              "hfov": math.radians(47.98), "moving": False}  # fmt: skip
    return SimpleNamespace(**{**fields, **kw})


def test_video_wording_for_both_codecs():
    assert video_text(_video()) == "704x576 at 15 fps, compression 30"
    assert video_text(_video(codec="h264")) == "704x576 at 15 fps, H.264 1000 kbit/s (up to 1500 with feedback)"
    # a ceiling at (or below) the start: feedback never raises the bitrate, so no "up to"
    assert video_text(_video(codec="h264", h264_max_bitrate_kbps=1000)) == "704x576 at 15 fps, H.264 1000 kbit/s"
    assert video_text(_video(codec="h264", h264_max_bitrate_kbps=800)) == "704x576 at 15 fps, H.264 1000 kbit/s"
    assert view.video_text is video_text  # the console's page line and answers use the same words


def test_ptz_wording():
    assert ptz_text(None) == "PTZ: waiting for ptz/state"
    assert ptz_text(_ptz()) == "pan  -11.00 deg  tilt  +0.00 deg  zoom   321 (1.4x, hfov 48.0 deg)"
    assert ptz_text(_ptz(tilt=-1e-9, moving=True)).startswith("pan  -11.00 deg  tilt  +0.00 deg")  # no "-0.00"
    assert ptz_text(_ptz(moving=True)).endswith("  moving")


def test_the_status_line():
    assert status_line(None, None, 1) == "PTZ: waiting for ptz/state | video: waiting | step 1 | ? help"
    assert status_line(_ptz(), _video(compression=40), 4) == (
        "pan  -11.00 deg  tilt  +0.00 deg  zoom   321 (1.4x, hfov 48.0 deg) | "
        "video: 704x576 at 15 fps, compression 40 | step 4 | ? help"
    )
    h264 = status_line(None, _video(codec="h264", h264_bitrate_kbps=700, h264_max_bitrate_kbps=1000), 2)
    assert "| video: 704x576 at 15 fps, H.264 700 kbit/s (up to 1000 with feedback) | step 2" in h264
