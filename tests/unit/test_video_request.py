"""What the stream node asks of the camera (streaming/video_request.py). ROS-free."""

from __future__ import annotations

import pytest

from axis_ptz_ros2.streaming.video_request import AUTO_PLACEHOLDER, camera_request, largest, share_request
from axis_ptz_ros2.streaming.video_types import VideoSettings
from axis_ptz_ros2.vapix.errors import InvalidArgument
from axis_ptz_ros2.vapix.models import Resolution

pytestmark = pytest.mark.unit

LISTED = (Resolution(640, 480), Resolution(1280, 720), Resolution(1024, 768), Resolution(1280, 960))


def test_resolution_auto_is_the_largest_listed_and_the_placeholder_before_the_list() -> None:
    auto = VideoSettings(resolution="", fps=15, compression=40)
    assert camera_request(auto, LISTED, h264=False).resolution == Resolution(1280, 960)
    assert camera_request(auto, None, h264=False).resolution == AUTO_PLACEHOLDER
    assert largest((Resolution(800, 600), Resolution(600, 800))) == Resolution(800, 600)  # as many pixels: wider
    asked = camera_request(VideoSettings(resolution="CIF", fps=15, compression=40), LISTED, h264=False, camera=2)
    assert (asked.resolution, asked.fps, asked.compression, asked.camera) == (Resolution(352, 288), 15, 40, 2)


def test_h264_asks_the_camera_for_its_best_jpeg_and_the_share_for_the_compression_asked() -> None:
    s = VideoSettings(resolution="1280x720", fps=25, compression=60, codec="h264")
    assert camera_request(s, LISTED, h264=True).compression == 0
    assert camera_request(s, LISTED, h264=False).compression == 60  # H.264 not possible here: MJPEG as asked
    share = share_request(s, LISTED)
    assert (share.resolution, share.fps, share.compression) == (Resolution(1280, 720), 25, 60)


def test_a_resolution_that_cannot_be_parsed_is_refused() -> None:
    with pytest.raises(InvalidArgument):
        camera_request(VideoSettings(resolution="huge"), LISTED, h264=False)
