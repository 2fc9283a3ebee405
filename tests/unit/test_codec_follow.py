"""The codec a consumer watches (axis_ptz_ros2.codec_follow): its own choice, or what the stream announces."""

from __future__ import annotations

import pytest

from axis_ptz_ros2.codec_follow import CHOICES, WAITING_TEXT, CodecFollower, check_choice

pytestmark = pytest.mark.unit


def test_auto_watches_nothing_until_the_stream_announces_then_follows_each_change() -> None:
    f = CodecFollower("auto")
    assert f.follows
    assert f.codec == ""
    assert f.describe() == WAITING_TEXT
    assert f.announce("h264") is True
    assert f.codec == "h264"
    assert f.announce("h264") is False  # the same codec again (a bandwidth step's video/params): no switch
    assert f.announce("mjpeg") is True
    assert f.codec == "mjpeg"
    assert "following" in f.describe()


def test_an_announced_codec_it_cannot_follow_means_nothing_watched_with_the_reason() -> None:
    f = CodecFollower("auto")
    f.announce("h264")
    assert f.announce("vp9") is True
    assert f.codec == ""
    assert "'vp9'" in f.problem
    assert "'vp9'" in f.describe()
    assert f.announce("mjpeg") is True
    assert f.codec == "mjpeg"
    assert f.problem == ""


@pytest.mark.parametrize("choice", ["mjpeg", "h264"])
def test_an_explicit_choice_ignores_the_stream(choice: str) -> None:
    f = CodecFollower(choice)
    assert not f.follows
    assert f.codec == choice
    other = "h264" if choice == "mjpeg" else "mjpeg"
    assert f.announce(other) is False
    assert f.codec == choice
    assert f.announced == other


@pytest.mark.parametrize("bad", ["", "MJPEG", "jpeg", "h265", "auto "])
def test_an_unknown_choice_is_refused_with_the_reason(bad: str) -> None:
    assert check_choice(bad) == f"codec={bad!r} is not one of auto, mjpeg, h264"
    with pytest.raises(ValueError, match="is not one of auto, mjpeg, h264"):
        CodecFollower(bad)
    assert CHOICES == ("auto", "mjpeg", "h264")
