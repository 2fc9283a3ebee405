"""Regressions from the ROS-input fuzz tier (issue 25): image sizes and boxes are refused when they are not a real
image's, before any arithmetic (a box corner at 1e308 overflowed inside the centring maths; a size of 2^32 - 1 px,
what a uint32 field carries, was accepted)."""

from __future__ import annotations

import math

import pytest

from axis_ptz_ros2.config import load_camera_model
from axis_ptz_ros2.ptz.backend import PtzLimitsRos, PtzReading
from axis_ptz_ros2.ptz.control import area_zoom_command
from axis_ptz_ros2.ptz.goals import wait_timeout
from axis_ptz_ros2.ptz.requests import stream_size
from axis_ptz_ros2.vapix.models import MAX_IMAGE_SIDE

pytestmark = pytest.mark.unit
ZOOM = load_camera_model().zoom
READING = PtzReading(0.0, 0.0, 1.0, 1)
LIMITS = PtzLimitsRos(-math.pi, math.pi, -0.5, 1.57, 1.0, 9999.0)


@pytest.mark.parametrize(
    "box",
    [(1e308, -math.pi, 10000.0, 5e-324), (0.0, 0.0, 1e308, 1e308), (-1.0, 0.0, 10.0, 10.0), (0.0, 0.0, 705.0, 10.0)],
)
def test_a_box_outside_the_image_is_refused_with_the_reason(box: tuple[float, float, float, float]) -> None:
    with pytest.raises(ValueError, match="not inside the 704x576 image"):
        area_zoom_command(READING, box, 704, 576, ZOOM, LIMITS)


def test_a_box_inside_the_image_still_zooms() -> None:
    pan, tilt, zoom = area_zoom_command(READING, (300.0, 250.0, 404.0, 326.0), 704, 576, ZOOM, LIMITS)
    assert math.isfinite(pan)
    assert math.isfinite(tilt)
    assert zoom > 1.0


def test_sizes_beyond_a_real_image_are_refused_by_the_request_layer() -> None:
    from axis_ptz_ros2.ptz.requests import Requests

    requests = Requests.__new__(Requests)  # size() needs only the stream's size
    requests._image_size = lambda: (704, 576)  # noqa: SLF001
    assert requests.size(0, 0) == (704, 576)
    assert requests.size(352, 288) == (352, 288)
    for width, height in ((2**32 - 1, 288), (352, MAX_IMAGE_SIDE + 1)):
        with pytest.raises(ValueError, match="outside 1..16384"):
            requests.size(width, height)


def test_a_defect_in_one_command_fails_that_command_and_the_slot_lives_on() -> None:
    """Found by the ROS-input fuzz tier in the full suite: speed 1e308 overflowed while the request was built; the
    exception ended the command thread and every later service call waited forever for acceptance."""
    from axis_ptz_ros2.ptz.command_slot import CommandSlot, Outcome

    class CameraError(Exception):
        pass

    slot = CommandSlot(error_types=(CameraError,))
    slot.start()
    try:
        bad = slot.submit("bad", lambda: int(round(math.inf)), supersedable=False)
        assert bad.wait(5.0)
        assert bad.outcome is Outcome.FAILED
        assert "internal error: OverflowError" in bad.error
        good = slot.submit("good", lambda: None, supersedable=False)
        assert good.wait(5.0)
        assert good.outcome is Outcome.SENT
    finally:
        slot.stop()


def test_a_speed_outside_0_to_1_is_refused_with_the_reason() -> None:
    from axis_ptz_ros2.ptz.requests import Requests

    requests = Requests.__new__(Requests)
    refusals: list[str] = []

    class Cmd:
        def refuse(self, label: str, reason: str) -> str:
            refusals.append(reason)
            return reason

        def move(self, *args: object, **kwargs: object) -> str:
            return "moved"

    requests._cmd = Cmd()  # type: ignore[assignment]  # noqa: SLF001
    assert requests.move("absolute", 0.1, 0.0, math.nan, 1e308, relative=False) == refusals[-1]
    assert "speed 1e+308 outside 0..1" in refusals[-1]
    assert requests.move("absolute", 0.1, 0.0, math.nan, 0.5, relative=False) == "moved"


@pytest.mark.parametrize(
    ("given", "expected"),
    [(2.5, 2.5), (0.0, 15.0), (-1.0, 15.0), (math.nan, 15.0), (math.inf, 15.0), (-math.inf, 15.0)],
)
def test_a_service_timeout_falls_back_to_wait_timeout(given, expected):
    assert wait_timeout(given, 15.0) == expected


@pytest.mark.parametrize(
    ("size", "expected"),
    [((704, 576), (704, 576)), ((0, 576), None), ((704, 0), None), ((-1, 5), None), ((MAX_IMAGE_SIDE + 1, 5), None)],
)
def test_only_a_usable_published_stream_size_is_followed(size, expected):
    assert stream_size(*size) == expected
